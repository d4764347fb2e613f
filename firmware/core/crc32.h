/* CRC-32/IEEE (zlib's crc32): reflected polynomial 0xEDB88320, init and final XOR 0xFFFFFFFF. */
#ifndef IRDAQ_CRC32_H
#define IRDAQ_CRC32_H

#include <stddef.h>
#include <stdint.h>

/* Continue a CRC: start with crc = 0 for a new message (the inversions are inside). */
uint32_t irdaq_crc32(uint32_t crc, const uint8_t *data, size_t n);

#endif
