/* The IRDAQ-4 board's portable core (docs/daq_protocol.md): commands in, frames out.
 *
 * No hardware and no operating system here.  A hardware layer (the STM32F411 board, or
 * the host build behind a pty) owns the sample clock and the link: it feeds received
 * command bytes to irdaq_receive(), hands each sample instant to irdaq_push_sample(),
 * and sends what accumulates in core->tx (whole frames, in order) to the host.
 * All functions are called from one context (the main loop): nothing here is reentrant.
 */
#ifndef IRDAQ_H
#define IRDAQ_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ring.h"

#define IRDAQ_CLOCK_HZ 10000000u      /* the sample clock is this divided by an integer */
#define IRDAQ_MAX_CHANNELS 4
#define IRDAQ_MAX_SAMPLES_PER_FRAME 256 /* the reference firmware's cap (the protocol's: 1024) */
#define IRDAQ_MIN_FRAMES_PER_S 100      /* a frame leaves at least every 10 ms */
#define IRDAQ_FRAME_OVERHEAD 16
#define IRDAQ_MAX_DATA_FRAME \
    (IRDAQ_FRAME_OVERHEAD + IRDAQ_MAX_SAMPLES_PER_FRAME * (IRDAQ_MAX_CHANNELS + 1) * 2)
#define IRDAQ_MAX_REPLY 1024
#define IRDAQ_MAX_LINE 128 /* command bytes before the LF (docs: at most 127 and the LF) */
#define IRDAQ_FIRMWARE_VERSION "1.0.0"

#define IRDAQ_FRAME_DATA 0x01u
#define IRDAQ_FRAME_REPLY 0x02u

/* Who the board says it is (IDN?) and the limits it enforces. */
typedef struct {
    const char *model;
    const char *serial;
    const char *firmware;
    double min_rate_hz;
    double max_rate_hz;
    unsigned adc_bits;
    double range_v;
} irdaq_identity;

/* The acquisition the host configured (CONF). */
typedef struct {
    uint32_t divider;       /* sample rate = IRDAQ_CLOCK_HZ / divider */
    uint8_t mask;           /* bit k: analog input k in every sample */
    uint8_t n_analog;       /* bits set in mask */
    uint8_t channels[IRDAQ_MAX_CHANNELS]; /* the enabled inputs, ascending */
    uint16_t samples_per_frame;
} irdaq_config;

/* What the hardware layer does when the core changes state. Any pointer may be NULL. */
typedef struct {
    void (*start)(void *context, const irdaq_config *config); /* clock from sample 0 */
    void (*stop)(void *context);
    /* A finished data frame found no room in tx: its samples are skipped (never sent). */
    void (*frame_skipped)(void *context, uint64_t first_index, uint32_t n_samples);
} irdaq_hooks;

typedef struct {
    irdaq_identity identity;
    irdaq_hooks hooks;
    void *context;
    irdaq_ring tx; /* frames waiting for the link */
    uint16_t max_samples_per_frame;

    irdaq_config config;
    bool streaming;
    uint64_t next_index; /* running index of the first sample of the frame being filled */
    uint16_t filled;     /* samples in the frame being filled */
    uint8_t frame[IRDAQ_MAX_DATA_FRAME];

    char line[IRDAQ_MAX_LINE + 1];
    uint16_t line_length;
    bool discarding; /* a line grew too long: drop bytes up to its LF */
    char reply[IRDAQ_MAX_REPLY + 1];
    uint16_t reply_length;
    bool reply_pending; /* a reply waits for room in tx; commands wait behind it */

    uint64_t samples_skipped;
    uint32_t frames_skipped;
} irdaq_core;

/* Power-up: stopped, input 0 at 10 kHz.  The tx ring must hold at least one data frame
 * and one reply (IRDAQ_MAX_DATA_FRAME + IRDAQ_FRAME_OVERHEAD + IRDAQ_MAX_REPLY bytes). */
void irdaq_init(irdaq_core *core, const irdaq_identity *identity, const irdaq_hooks *hooks,
                void *context, uint8_t *tx_buffer, size_t tx_size,
                uint16_t max_samples_per_frame);

/* Feed bytes from the host; returns how many were taken (fewer while a reply waits for
 * room in tx: offer the rest again after the link has sent some). */
size_t irdaq_receive(irdaq_core *core, const uint8_t *data, size_t n);

/* One sample instant: the counts of the enabled inputs (ascending) and the digital word. */
void irdaq_push_sample(irdaq_core *core, const int16_t *analog, uint16_t digital);

/* The hardware lost n sample instants (e.g. its DMA was overrun): the frame being filled
 * is dropped with them and the index moves on, so the host sees the gap. */
void irdaq_lose_samples(irdaq_core *core, uint32_t n);

/* Call after the link sent bytes: a waiting reply goes out as soon as it fits. */
void irdaq_poll(irdaq_core *core);

/* Bytes one data frame of the current configuration takes. */
size_t irdaq_data_frame_bytes(const irdaq_core *core);

/* Interpret one command line (no LF) into the reply text; used by irdaq_receive. */
void irdaq_command(irdaq_core *core, const char *line, size_t length, char *reply,
                   size_t reply_size);

/* The configuration a CONF for rate_hz and these channels gives (rate already in range). */
irdaq_config irdaq_config_for(const irdaq_core *core, double rate_hz, uint8_t mask);

#endif
