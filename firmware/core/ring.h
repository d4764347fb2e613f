/* Byte FIFO between the frame builder and the link: whole frames go in or nothing does. */
#ifndef IRDAQ_RING_H
#define IRDAQ_RING_H

#include <stddef.h>
#include <stdint.h>

typedef struct {
    uint8_t *buffer;
    size_t size;
    size_t start; /* where the oldest byte is */
    size_t used;  /* bytes waiting */
} irdaq_ring;

void irdaq_ring_init(irdaq_ring *ring, uint8_t *buffer, size_t size);
size_t irdaq_ring_used(const irdaq_ring *ring);
size_t irdaq_ring_free(const irdaq_ring *ring);
/* Append all n bytes, or none when they do not fit (returns 1 when written). */
int irdaq_ring_write(irdaq_ring *ring, const uint8_t *data, size_t n);
/* Copy n bytes starting offset bytes after the oldest, without consuming them. */
void irdaq_ring_peek(const irdaq_ring *ring, size_t offset, uint8_t *out, size_t n);
/* The oldest bytes as one contiguous piece (up to the buffer's end); returns its length. */
size_t irdaq_ring_contiguous(const irdaq_ring *ring, const uint8_t **data);
void irdaq_ring_consume(irdaq_ring *ring, size_t n);

#endif
