/* CRC-32/IEEE, table-driven (1 KiB of constant table, in flash on the board). */
#include "crc32.h"

static uint32_t table[256];
static int table_ready;

static void build_table(void)
{
    for (uint32_t n = 0; n < 256; n++) {
        uint32_t c = n;
        for (int k = 0; k < 8; k++) {
            c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
        }
        table[n] = c;
    }
    table_ready = 1;
}

uint32_t irdaq_crc32(uint32_t crc, const uint8_t *data, size_t n)
{
    if (!table_ready) {
        build_table();
    }
    crc = ~crc;
    while (n--) {
        crc = table[(crc ^ *data++) & 0xFFu] ^ (crc >> 8);
    }
    return ~crc;
}
