/* The core's state machine: command lines in, reply frames and data frames into the tx ring.
 *
 * Sample scheduler: samples arrive one instant at a time and fill the frame being built
 * in place (header, payload, CRC in one buffer).  A full frame goes into tx whole, or,
 * when tx has no room (the host does not read, the link hangs), is skipped: its samples
 * are counted, its indices are never sent, and the next frame's index shows the gap.
 */
#include "irdaq.h"

#include <math.h>
#include <string.h>

#include "crc32.h"

static const uint8_t SYNC[4] = {0xA5, 0x5A, 0xC3, 0x3C};

static void put_u16(uint8_t *at, uint16_t value)
{
    at[0] = (uint8_t)value;
    at[1] = (uint8_t)(value >> 8);
}

static void put_u32(uint8_t *at, uint32_t value)
{
    for (int k = 0; k < 4; k++) {
        at[k] = (uint8_t)(value >> (8 * k));
    }
}

/* Sync, header and CRC around a payload already at buffer + 12. */
static size_t seal_frame(uint8_t *buffer, uint8_t type, uint8_t mask, uint16_t length,
                         uint32_t first_index)
{
    memcpy(buffer, SYNC, sizeof SYNC);
    buffer[4] = type;
    buffer[5] = mask;
    put_u16(buffer + 6, length);
    put_u32(buffer + 8, first_index);
    put_u32(buffer + 12 + length, irdaq_crc32(0, buffer + 4, 8u + length));
    return IRDAQ_FRAME_OVERHEAD + (size_t)length;
}

irdaq_config irdaq_config_for(const irdaq_core *core, double rate_hz, uint8_t mask)
{
    irdaq_config config;
    memset(&config, 0, sizeof config);
    double divider = nearbyint((double)IRDAQ_CLOCK_HZ / rate_hz); /* ties to even */
    config.divider = divider < 1.0 ? 1u : (uint32_t)divider;
    config.mask = mask;
    for (uint8_t k = 0; k < IRDAQ_MAX_CHANNELS; k++) {
        if (mask >> k & 1u) {
            config.channels[config.n_analog++] = k;
        }
    }
    uint32_t per_frame = IRDAQ_CLOCK_HZ / IRDAQ_MIN_FRAMES_PER_S / config.divider;
    if (per_frame > core->max_samples_per_frame) {
        per_frame = core->max_samples_per_frame;
    }
    config.samples_per_frame = (uint16_t)(per_frame ? per_frame : 1u);
    return config;
}

void irdaq_init(irdaq_core *core, const irdaq_identity *identity, const irdaq_hooks *hooks,
                void *context, uint8_t *tx_buffer, size_t tx_size,
                uint16_t max_samples_per_frame)
{
    memset(core, 0, sizeof *core);
    core->identity = *identity;
    if (hooks) {
        core->hooks = *hooks;
    }
    core->context = context;
    irdaq_ring_init(&core->tx, tx_buffer, tx_size);
    if (max_samples_per_frame < 1 || max_samples_per_frame > IRDAQ_MAX_SAMPLES_PER_FRAME) {
        max_samples_per_frame = IRDAQ_MAX_SAMPLES_PER_FRAME;
    }
    core->max_samples_per_frame = max_samples_per_frame;
    core->config = irdaq_config_for(core, 10000.0, 0x01u);
}

size_t irdaq_data_frame_bytes(const irdaq_core *core)
{
    return IRDAQ_FRAME_OVERHEAD +
           (size_t)core->config.samples_per_frame * (core->config.n_analog + 1u) * 2u;
}

/* Put the waiting reply into tx if it fits now. */
static void flush_reply(irdaq_core *core)
{
    if (!core->reply_pending) {
        return;
    }
    static uint8_t frame[IRDAQ_FRAME_OVERHEAD + IRDAQ_MAX_REPLY];
    memcpy(frame + 12, core->reply, core->reply_length);
    size_t n = seal_frame(frame, IRDAQ_FRAME_REPLY, 0, core->reply_length, 0);
    if (irdaq_ring_write(&core->tx, frame, n)) {
        core->reply_pending = false;
    }
}

void irdaq_poll(irdaq_core *core)
{
    flush_reply(core);
}

static void skip_frame(irdaq_core *core, uint64_t first, uint32_t n)
{
    core->samples_skipped += n;
    core->frames_skipped++;
    if (core->hooks.frame_skipped) {
        core->hooks.frame_skipped(core->context, first, n);
    }
}

static void finish_frame(irdaq_core *core)
{
    const irdaq_config *config = &core->config;
    uint16_t length = (uint16_t)(config->samples_per_frame * (config->n_analog + 1u) * 2u);
    size_t n = seal_frame(core->frame, IRDAQ_FRAME_DATA, config->mask, length,
                          (uint32_t)core->next_index);
    flush_reply(core); /* a reply that waited for room goes first */
    if (core->reply_pending || !irdaq_ring_write(&core->tx, core->frame, n)) {
        skip_frame(core, core->next_index, config->samples_per_frame);
    }
    core->next_index += config->samples_per_frame;
    core->filled = 0;
}

void irdaq_push_sample(irdaq_core *core, const int16_t *analog, uint16_t digital)
{
    if (!core->streaming) {
        return;
    }
    const irdaq_config *config = &core->config;
    uint8_t *at = core->frame + 12 + (size_t)core->filled * (config->n_analog + 1u) * 2u;
    for (uint8_t k = 0; k < config->n_analog; k++) {
        put_u16(at, (uint16_t)analog[k]);
        at += 2;
    }
    put_u16(at, digital);
    if (++core->filled == config->samples_per_frame) {
        finish_frame(core);
    }
}

void irdaq_lose_samples(irdaq_core *core, uint32_t n)
{
    if (!core->streaming || (n == 0 && core->filled == 0)) {
        return;
    }
    uint32_t lost = core->filled + n;
    skip_frame(core, core->next_index, lost);
    core->next_index += lost;
    core->filled = 0;
}

static void queue_reply(irdaq_core *core, const char *text)
{
    size_t n = strlen(text);
    if (n > IRDAQ_MAX_REPLY) {
        n = IRDAQ_MAX_REPLY;
    }
    memcpy(core->reply, text, n);
    core->reply_length = (uint16_t)n;
    core->reply_pending = true;
    flush_reply(core);
}

static void run_line(irdaq_core *core)
{
    /* the reference strips a CR and spaces around the line before interpreting it */
    size_t start = 0, end = core->line_length;
    while (start < end && (core->line[start] == '\r' || core->line[start] == ' ')) {
        start++;
    }
    while (end > start && (core->line[end - 1] == '\r' || core->line[end - 1] == ' ')) {
        end--;
    }
    bool was_streaming = core->streaming;
    char reply[IRDAQ_MAX_REPLY + 1];
    irdaq_command(core, core->line + start, end - start, reply, sizeof reply);
    if (core->streaming && !was_streaming) { /* START: a fresh stream from index 0 */
        core->next_index = 0;
        core->filled = 0;
        queue_reply(core, reply);
        if (core->hooks.start) {
            core->hooks.start(core->context, &core->config);
        }
        return;
    }
    if (was_streaming && !core->streaming) { /* STOP: the partial frame is never sent */
        core->filled = 0;
        if (core->hooks.stop) {
            core->hooks.stop(core->context);
        }
    }
    queue_reply(core, reply);
}

size_t irdaq_receive(irdaq_core *core, const uint8_t *data, size_t n)
{
    size_t taken = 0;
    while (taken < n) {
        flush_reply(core);
        if (core->reply_pending) {
            break; /* one reply at a time: the next command waits for room */
        }
        uint8_t c = data[taken++];
        if (c == '\n') {
            if (!core->discarding) {
                run_line(core);
            }
            core->discarding = false;
            core->line_length = 0;
        } else if (core->discarding) {
            continue;
        } else if (core->line_length == IRDAQ_MAX_LINE) {
            queue_reply(core, "ERR command line too long");
            core->discarding = true;
            core->line_length = 0;
        } else {
            core->line[core->line_length++] = (char)c;
        }
    }
    return taken;
}
