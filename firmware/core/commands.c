/* The command interpreter: IDN?, CONF, CONF?, START, STOP and their error replies, worded
 * exactly as docs/daq_protocol.md and the reference emulator word them. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "irdaq.h"
#include "textfmt.h"

#define MAX_WORDS 4

typedef struct {
    const char *start[MAX_WORDS];
    size_t length[MAX_WORDS];
    int count; /* words found (may exceed MAX_WORDS: only the first are kept) */
} words;

static bool is_space(char c)
{
    /* what Python's str.split() splits on, within ASCII */
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f' ||
           (c >= 0x1c && c <= 0x1f);
}

static words split(const char *line, size_t n)
{
    words found = {{0}, {0}, 0};
    size_t at = 0;
    while (at < n) {
        while (at < n && is_space(line[at])) {
            at++;
        }
        if (at == n) {
            break;
        }
        size_t begin = at;
        while (at < n && !is_space(line[at])) {
            at++;
        }
        if (found.count < MAX_WORDS) {
            found.start[found.count] = line + begin;
            found.length[found.count] = at - begin;
        }
        found.count++;
    }
    return found;
}

static bool word_equals(const words *w, int k, const char *upper)
{
    size_t n = strlen(upper);
    if (w->length[k] != n) {
        return false;
    }
    for (size_t i = 0; i < n; i++) {
        char c = w->start[k][i];
        if (c >= 'a' && c <= 'z') {
            c = (char)(c - 'a' + 'A');
        }
        if (c != upper[i]) {
            return false;
        }
    }
    return true;
}

static void reply_identity(const irdaq_core *core, char *reply, size_t size)
{
    const irdaq_identity *id = &core->identity;
    char low[32], high[32], range[32];
    irdaq_format_g(low, sizeof low, id->min_rate_hz);
    irdaq_format_g(high, sizeof high, id->max_rate_hz);
    irdaq_format_g(range, sizeof range, id->range_v);
    snprintf(reply, size,
             "OK model=%s serial=%s firmware=%s channels=%d min_rate_hz=%s max_rate_hz=%s "
             "adc_bits=%u range_v=%s",
             id->model, id->serial, id->firmware, IRDAQ_MAX_CHANNELS, low, high, id->adc_bits,
             range);
}

static void reply_configuration(const irdaq_core *core, char *reply, size_t size)
{
    const irdaq_config *config = &core->config;
    char rate[40], channels[16];
    irdaq_format_shortest(rate, sizeof rate, (double)IRDAQ_CLOCK_HZ / config->divider);
    size_t at = 0;
    for (uint8_t k = 0; k < config->n_analog; k++) {
        at += (size_t)snprintf(channels + at, sizeof channels - at, k ? ",%u" : "%u",
                               config->channels[k]);
    }
    snprintf(reply, size, "OK rate_hz=%s channels=%s samples_per_frame=%u", rate, channels,
             config->samples_per_frame);
}

/* int(text) as Python reads it: [sign] digits with single underscores between digits.
 * Writes the value's decimal text (no sign for zero, no leading zeros) to out. */
static bool parse_integer(const char *text, size_t n, char *out, size_t size, bool *negative)
{
    size_t at = 0, written = 0;
    *negative = false;
    if (n && (text[0] == '+' || text[0] == '-')) {
        *negative = text[0] == '-';
        at = 1;
    }
    if (at == n) {
        return false;
    }
    bool leading = true;
    for (size_t i = at; i < n; i++) {
        char c = text[i];
        if (c == '_') {
            if (i == at || i + 1 == n || text[i + 1] == '_') {
                return false;
            }
            continue;
        }
        if (c < '0' || c > '9') {
            return false;
        }
        if (leading && c == '0') {
            continue;
        }
        leading = false;
        if (written + 1 < size) {
            out[written++] = c;
        }
    }
    if (written == 0) {
        out[written++] = '0';
        *negative = false;
    }
    out[written] = '\0';
    return true;
}

#define MAX_LIST 32

/* parse_channels() then the board's own checks, in the reference's order. */
static bool parse_channel_list(const char *text, size_t n, uint8_t *mask, char *reply,
                               size_t size)
{
    char list[IRDAQ_MAX_LINE + 1], quoted[4 * IRDAQ_MAX_LINE + 8];
    memcpy(list, text, n);
    list[n] = '\0';
    irdaq_format_repr(quoted, sizeof quoted, text, n);
    char values[MAX_LIST][24];
    bool negative[MAX_LIST];
    int count = 0;
    size_t begin = 0;
    for (size_t at = 0; at <= n; at++) {
        if (at < n && text[at] != ',') {
            continue;
        }
        if (count == MAX_LIST ||
            !parse_integer(text + begin, at - begin, values[count], sizeof values[count],
                           &negative[count])) {
            snprintf(reply, size, "ERR channel list %s is not comma-separated integers", quoted);
            return false;
        }
        count++;
        begin = at + 1;
    }
    for (int i = 0; i < count; i++) {
        for (int j = 0; j < i; j++) {
            if (negative[i] == negative[j] && strcmp(values[i], values[j]) == 0) {
                snprintf(reply, size, "ERR channel list %s names a channel twice", quoted);
                return false;
            }
        }
    }
    *mask = 0;
    int previous = -1;
    bool ascending = true;
    for (int i = 0; i < count; i++) {
        if (negative[i] || strlen(values[i]) > 1 || values[i][0] > '0' + IRDAQ_MAX_CHANNELS - 1) {
            snprintf(reply, size, "ERR analog channel %s%s does not exist (0..%d)",
                     negative[i] ? "-" : "", values[i], IRDAQ_MAX_CHANNELS - 1);
            return false;
        }
        int channel = values[i][0] - '0';
        ascending = ascending && channel > previous;
        previous = channel;
        *mask |= (uint8_t)(1u << channel);
    }
    if (!ascending) {
        snprintf(reply, size, "ERR channel list %s must be in ascending order", list);
        return false;
    }
    return true;
}

static void configure(irdaq_core *core, const words *w, char *reply, size_t size)
{
    if (core->streaming) {
        snprintf(reply, size, "ERR busy: STOP before CONF");
        return;
    }
    if (w->count != 3) {
        snprintf(reply, size,
                 "ERR CONF takes a rate in Hz and a channel list, e.g. CONF 20000 0,1");
        return;
    }
    char rate_text[IRDAQ_MAX_LINE + 1];
    memcpy(rate_text, w->start[1], w->length[1]);
    rate_text[w->length[1]] = '\0';
    double rate_hz;
    if (!irdaq_parse_float(rate_text, &rate_hz)) {
        char quoted[4 * IRDAQ_MAX_LINE + 8];
        irdaq_format_repr(quoted, sizeof quoted, w->start[1], w->length[1]);
        snprintf(reply, size, "ERR rate %s is not a number", quoted);
        return;
    }
    const irdaq_identity *id = &core->identity;
    if (!(id->min_rate_hz <= rate_hz && rate_hz <= id->max_rate_hz)) {
        char rate[32], low[32], high[32];
        irdaq_format_g(rate, sizeof rate, rate_hz);
        irdaq_format_g(low, sizeof low, id->min_rate_hz);
        irdaq_format_g(high, sizeof high, id->max_rate_hz);
        snprintf(reply, size, "ERR rate %s Hz out of range %s..%s", rate, low, high);
        return;
    }
    uint8_t mask;
    if (!parse_channel_list(w->start[2], w->length[2], &mask, reply, size)) {
        return;
    }
    core->config = irdaq_config_for(core, rate_hz, mask);
    reply_configuration(core, reply, size);
}

void irdaq_command(irdaq_core *core, const char *line, size_t length, char *reply,
                   size_t reply_size)
{
    words w = split(line, length);
    if (w.count == 0) {
        snprintf(reply, reply_size, "ERR empty command");
        return;
    }
    if (word_equals(&w, 0, "IDN?") && w.count == 1) {
        reply_identity(core, reply, reply_size);
    } else if (word_equals(&w, 0, "CONF?") && w.count == 1) {
        reply_configuration(core, reply, reply_size);
    } else if (word_equals(&w, 0, "CONF")) {
        configure(core, &w, reply, reply_size);
    } else if (word_equals(&w, 0, "START") && w.count == 1) {
        if (core->streaming) {
            snprintf(reply, reply_size, "ERR already streaming");
        } else {
            core->streaming = true;
            snprintf(reply, reply_size, "OK streaming=1");
        }
    } else if (word_equals(&w, 0, "STOP") && w.count == 1) {
        core->streaming = false;
        snprintf(reply, reply_size, "OK streaming=0 samples=%llu",
                 (unsigned long long)core->next_index);
    } else {
        /* the reference quotes the stripped line, cut to 40 characters */
        size_t begin = 0, end = length;
        while (begin < end && is_space(line[begin])) {
            begin++;
        }
        while (end > begin && is_space(line[end - 1])) {
            end--;
        }
        char quoted[4 * 40 + 8];
        irdaq_format_repr(quoted, sizeof quoted, line + begin, end - begin > 40 ? 40 : end - begin);
        snprintf(reply, reply_size, "ERR unknown command %s", quoted);
    }
}
