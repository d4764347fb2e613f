/* Byte FIFO: a start position and a fill count, so full and empty never alias. */
#include "ring.h"

#include <string.h>

void irdaq_ring_init(irdaq_ring *ring, uint8_t *buffer, size_t size)
{
    ring->buffer = buffer;
    ring->size = size;
    ring->start = 0;
    ring->used = 0;
}

size_t irdaq_ring_used(const irdaq_ring *ring)
{
    return ring->used;
}

size_t irdaq_ring_free(const irdaq_ring *ring)
{
    return ring->size - ring->used;
}

int irdaq_ring_write(irdaq_ring *ring, const uint8_t *data, size_t n)
{
    if (n > irdaq_ring_free(ring)) {
        return 0;
    }
    size_t at = (ring->start + ring->used) % ring->size;
    size_t first = ring->size - at < n ? ring->size - at : n;
    memcpy(ring->buffer + at, data, first);
    memcpy(ring->buffer, data + first, n - first);
    ring->used += n;
    return 1;
}

void irdaq_ring_peek(const irdaq_ring *ring, size_t offset, uint8_t *out, size_t n)
{
    size_t at = (ring->start + offset) % ring->size;
    size_t first = ring->size - at < n ? ring->size - at : n;
    memcpy(out, ring->buffer + at, first);
    memcpy(out + first, ring->buffer, n - first);
}

size_t irdaq_ring_contiguous(const irdaq_ring *ring, const uint8_t **data)
{
    *data = ring->buffer + ring->start;
    return ring->size - ring->start < ring->used ? ring->size - ring->start : ring->used;
}

void irdaq_ring_consume(irdaq_ring *ring, size_t n)
{
    ring->start = (ring->start + n) % ring->size;
    ring->used -= n;
}
