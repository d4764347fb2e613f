/* The firmware core on a PC: a pty stands in for the USB CDC port, a counter for the ADC.
 *
 * Prints the pty's slave path (what a driver opens, like /dev/ttyACM0) on its first line
 * of stdout, then serves until stdin closes.  The simulated sample source is the Python
 * emulator's CounterSource (hardware_sim/sample_source.py), computed from the running
 * sample index i of the stream:
 *     input 0: i mod 2^16 as int16        input 1: (3 i + 11) mod 2^16 as int16
 *     inputs 2, 3: 0                      digital bit 0 (tach): (i - phase) mod period < width
 * The clock runs --speed times real time from each START (inf: as fast as the link takes
 * frames, never skipping one).
 *
 * Link faults, for tests (a lossy cable between the board and the host, not the board):
 * lines on stdin arm them, as hardware_sim/daq_faults.py does for the Python emulator:
 *     garbage N | garbage_every N K | drop N FRAMES | corrupt FRAMES | corrupt_every K |
 *     stall | resume | unplug | clear | sync TOKEN
 * Every fault that touches a data frame, and every frame the core skipped because its
 * FIFO was full, is reported on stdout as "fault KIND FIRST_INDEX N_SAMPLES N_BYTES"
 * before the affected bytes reach the pty; "sync TOKEN" answers "synced TOKEN" after all
 * reports so far.
 */
#define _XOPEN_SOURCE 700
#define _DEFAULT_SOURCE

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "../core/irdaq.h"
#include "../core/ring.h"

#define OUT_CAPACITY (1u << 20)
#define MAX_ARMED 1024

typedef struct {
    double speed;
    long long tach_period, tach_width, tach_phase;
} source_settings;

typedef struct {
    int master, slave;
    bool unplugged;
    irdaq_core core;
    source_settings source;
    double started_s;
    uint64_t produced; /* sample instants taken since START */
    /* link */
    uint8_t out[OUT_CAPACITY];
    size_t out_length, out_sent;
    bool stalled;
    unsigned long long frames_seen;
    unsigned garbage[MAX_ARMED];
    int n_garbage;
    unsigned garbage_every, garbage_length;
    unsigned drops[MAX_ARMED];
    int n_drops;
    unsigned corrupt, corrupt_every;
    uint64_t random_state;
    /* commands from the pty not yet taken by the core */
    uint8_t in[4096];
    size_t in_length;
} host;

static host board;
static uint8_t tx_buffer_storage[1u << 22];

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static uint64_t next_random(host *h)
{
    uint64_t x = h->random_state; /* xorshift64 */
    x ^= x << 13;
    x ^= x >> 7;
    x ^= x << 17;
    h->random_state = x;
    return x;
}

static void report(const char *kind, uint64_t first, uint64_t n_samples, uint64_t n_bytes)
{
    printf("fault %s %llu %llu %llu\n", kind, (unsigned long long)first,
           (unsigned long long)n_samples, (unsigned long long)n_bytes);
    fflush(stdout);
}

/* --- the core's hooks -------------------------------------------------------------------- */
static void on_start(void *context, const irdaq_config *config)
{
    (void)config;
    host *h = context;
    h->started_s = now_s();
    h->produced = 0;
}

static void on_skipped(void *context, uint64_t first, uint32_t n)
{
    (void)context;
    report("overflow", first, n, 0);
}

/* --- the simulated ADC and tach ------------------------------------------------------------ */
static void take_sample(host *h)
{
    uint64_t i = h->produced++;
    const irdaq_config *config = &h->core.config;
    int16_t analog[IRDAQ_MAX_CHANNELS];
    for (uint8_t k = 0; k < config->n_analog; k++) {
        uint8_t input = config->channels[k];
        uint16_t counts = input == 0 ? (uint16_t)i : input == 1 ? (uint16_t)(3u * i + 11u) : 0;
        analog[k] = (int16_t)counts;
    }
    long long period = h->source.tach_period;
    long long phase = (((long long)i - h->source.tach_phase) % period + period) % period;
    irdaq_push_sample(&h->core, analog, phase < h->source.tach_width ? 1u : 0u);
}

static void run_clock(host *h)
{
    if (!h->core.streaming) {
        return;
    }
    if (isinf(h->source.speed)) { /* unpaced: a frame whenever the FIFO has room for it */
        size_t frame = irdaq_data_frame_bytes(&h->core);
        for (int k = 0; k < 64 && irdaq_ring_free(&h->core.tx) >= frame; k++) {
            for (uint16_t s = 0; s < h->core.config.samples_per_frame; s++) {
                take_sample(h);
            }
        }
        return;
    }
    double rate = (double)IRDAQ_CLOCK_HZ / h->core.config.divider;
    uint64_t due = (uint64_t)((now_s() - h->started_s) * rate * h->source.speed);
    while (h->produced < due && h->core.streaming) {
        take_sample(h);
    }
}

static double seconds_to_next_frame(const host *h)
{
    double rate = (double)IRDAQ_CLOCK_HZ / h->core.config.divider * h->source.speed;
    uint64_t target = h->produced + h->core.config.samples_per_frame - h->core.filled;
    double wait = h->started_s + (double)target / rate - now_s();
    return wait > 0 ? wait : 0;
}

/* --- the link: frames from the FIFO to the pty, with the armed faults -------------------- */
static void take_frame(host *h)
{
    irdaq_ring *tx = &h->core.tx;
    if (irdaq_ring_used(tx) < IRDAQ_FRAME_OVERHEAD) {
        return;
    }
    uint8_t header[12];
    irdaq_ring_peek(tx, 0, header, sizeof header);
    size_t length = (size_t)header[6] | (size_t)header[7] << 8;
    size_t n = IRDAQ_FRAME_OVERHEAD + length;
    uint8_t frame[IRDAQ_FRAME_OVERHEAD + IRDAQ_MAX_DATA_FRAME + IRDAQ_MAX_REPLY];
    irdaq_ring_peek(tx, 0, frame, n);
    irdaq_ring_consume(tx, n);
    h->out_length = h->out_sent = 0;
    if (header[4] != IRDAQ_FRAME_DATA) {
        memcpy(h->out, frame, n);
        h->out_length = n;
        return;
    }
    uint64_t first = (uint64_t)header[8] | (uint64_t)header[9] << 8 |
                     (uint64_t)header[10] << 16 | (uint64_t)header[11] << 24;
    unsigned words = 1;
    for (int k = 0; k < IRDAQ_MAX_CHANNELS; k++) {
        words += header[5] >> k & 1u;
    }
    uint64_t n_samples = length / (2u * words);
    h->frames_seen++;
    size_t garbage = 0;
    if (h->n_garbage) {
        garbage = h->garbage[0];
        memmove(h->garbage, h->garbage + 1, (size_t)--h->n_garbage * sizeof h->garbage[0]);
    }
    if (h->garbage_every && h->frames_seen % h->garbage_every == 0) {
        garbage += h->garbage_length;
    }
    if (garbage > OUT_CAPACITY - n) {
        garbage = OUT_CAPACITY - n;
    }
    for (size_t k = 0; k < garbage; k++) {
        h->out[h->out_length++] = (uint8_t)next_random(h);
    }
    if (garbage) {
        report("garbage", first, 0, garbage);
    }
    if (h->n_drops) {
        size_t drop = h->drops[0];
        memmove(h->drops, h->drops + 1, (size_t)--h->n_drops * sizeof h->drops[0]);
        if (drop > n / 2) {
            drop = n / 2;
        }
        size_t high = n - 4 - drop > 13 ? n - 4 - drop : 13;
        size_t at = 12 + (size_t)(next_random(h) % (high - 12));
        memmove(frame + at, frame + at + drop, n - at - drop);
        n -= drop;
        report("dropped_bytes", first, n_samples, drop);
    } else if (h->corrupt || (h->corrupt_every && h->frames_seen % h->corrupt_every == 0)) {
        if (h->corrupt) {
            h->corrupt--;
        }
        frame[n - 1] ^= 0xFFu;
        report("corrupt_crc", first, n_samples, 0);
    }
    memcpy(h->out + h->out_length, frame, n);
    h->out_length += n;
}

static void run_link(host *h)
{
    while (!h->unplugged && !h->stalled) {
        if (h->out_sent == h->out_length) {
            take_frame(h);
            irdaq_poll(&h->core); /* a reply waiting for room may fit now */
            if (h->out_sent == h->out_length) {
                return;
            }
        }
        ssize_t written = write(h->master, h->out + h->out_sent, h->out_length - h->out_sent);
        if (written <= 0) {
            return; /* the pty is full (EAGAIN): the host is not reading */
        }
        h->out_sent += (size_t)written;
    }
}

static void feed_commands(host *h)
{
    if (h->in_length) {
        size_t taken = irdaq_receive(&h->core, h->in, h->in_length);
        memmove(h->in, h->in + taken, h->in_length - taken);
        h->in_length -= taken;
    }
}

static void unplug(host *h)
{
    if (!h->unplugged) {
        close(h->master);
        close(h->slave);
        h->unplugged = true;
    }
}

/* --- control lines on stdin ------------------------------------------------------------------ */
static bool control(host *h, char *line)
{
    unsigned a = 0, b = 0;
    char token[64];
    if (sscanf(line, "garbage_every %u %u", &a, &b) == 2) {
        h->garbage_length = a;
        h->garbage_every = b;
    } else if (sscanf(line, "garbage %u", &a) == 1 && h->n_garbage < MAX_ARMED) {
        h->garbage[h->n_garbage++] = a;
    } else if (sscanf(line, "drop %u %u", &a, &b) == 2) {
        for (unsigned k = 0; k < b && h->n_drops < MAX_ARMED; k++) {
            h->drops[h->n_drops++] = a;
        }
    } else if (sscanf(line, "corrupt_every %u", &a) == 1) {
        h->corrupt_every = a;
    } else if (sscanf(line, "corrupt %u", &a) == 1) {
        h->corrupt += a;
    } else if (strncmp(line, "stall", 5) == 0) {
        h->stalled = true;
    } else if (strncmp(line, "resume", 6) == 0) {
        h->stalled = false;
    } else if (strncmp(line, "unplug", 6) == 0) {
        unplug(h);
    } else if (strncmp(line, "clear", 5) == 0) {
        h->n_garbage = h->n_drops = 0;
        h->garbage_every = h->corrupt = h->corrupt_every = 0;
        h->stalled = false;
    } else if (sscanf(line, "sync %63s", token) == 1) {
        printf("synced %s\n", token);
        fflush(stdout);
    } else {
        fprintf(stderr, "irdaq-host: unknown control line: %s", line);
    }
    return true;
}

static bool read_control(host *h)
{
    static char pending[4096];
    static size_t length;
    ssize_t n = read(STDIN_FILENO, pending + length, sizeof pending - 1 - length);
    if (n <= 0) {
        return false; /* stdin closed: the parent is done with us */
    }
    length += (size_t)n;
    char *newline;
    while ((newline = memchr(pending, '\n', length)) != NULL) {
        *newline = '\0';
        char line[4096];
        size_t k = (size_t)(newline - pending);
        memcpy(line, pending, k + 1);
        strcat(line, "\n");
        control(h, line);
        memmove(pending, newline + 1, length - k - 1);
        length -= k + 1;
    }
    return true;
}

/* --- setup ------------------------------------------------------------------------------------ */
static void usage(void)
{
    fprintf(stderr,
            "usage: irdaq-host [--speed X|inf] [--fifo-bytes N] [--samples-per-frame N]\n"
            "       [--tach-period N] [--tach-width N] [--tach-phase N] [--seed N]\n"
            "       [--serial TEXT] [--model TEXT] [--max-rate-hz X] [--min-rate-hz X]\n");
    exit(2);
}

static int open_pty(host *h)
{
    h->master = posix_openpt(O_RDWR | O_NOCTTY);
    if (h->master < 0 || grantpt(h->master) || unlockpt(h->master)) {
        perror("irdaq-host: pty");
        return -1;
    }
    const char *name = ptsname(h->master);
    h->slave = name ? open(name, O_RDWR | O_NOCTTY) : -1; /* held open: the port stays */
    if (h->slave < 0) {
        perror("irdaq-host: pty slave");
        return -1;
    }
    struct termios raw;
    tcgetattr(h->slave, &raw);
    cfmakeraw(&raw); /* no echo, no line editing: bytes pass untouched */
    tcsetattr(h->slave, TCSANOW, &raw);
    fcntl(h->master, F_SETFL, fcntl(h->master, F_GETFL) | O_NONBLOCK);
    printf("%s\n", name);
    fflush(stdout);
    return 0;
}

int main(int argc, char **argv)
{
    host *h = &board;
    irdaq_identity identity = {"IRDAQ-4", "HOST0001", IRDAQ_FIRMWARE_VERSION, 10.0, 250000.0,
                               16, 10.0};
    size_t fifo_bytes = 64u * 1024u;
    unsigned long max_per_frame = IRDAQ_MAX_SAMPLES_PER_FRAME;
    h->source = (source_settings){1.0, 1000, 10, 0};
    h->random_state = 0x9E3779B97F4A7C15ull;
    for (int k = 1; k < argc; k++) {
        if (k + 1 >= argc) {
            usage();
        }
        const char *option = argv[k], *value = argv[++k];
        if (!strcmp(option, "--speed")) {
            h->source.speed = strtod(value, NULL);
        } else if (!strcmp(option, "--fifo-bytes")) {
            fifo_bytes = strtoul(value, NULL, 10);
        } else if (!strcmp(option, "--samples-per-frame")) {
            max_per_frame = strtoul(value, NULL, 10);
        } else if (!strcmp(option, "--tach-period")) {
            h->source.tach_period = strtoll(value, NULL, 10);
        } else if (!strcmp(option, "--tach-width")) {
            h->source.tach_width = strtoll(value, NULL, 10);
        } else if (!strcmp(option, "--tach-phase")) {
            h->source.tach_phase = strtoll(value, NULL, 10);
        } else if (!strcmp(option, "--seed")) {
            h->random_state ^= strtoull(value, NULL, 10) * 0xBF58476D1CE4E5B9ull;
        } else if (!strcmp(option, "--serial")) {
            identity.serial = value;
        } else if (!strcmp(option, "--model")) {
            identity.model = value;
        } else if (!strcmp(option, "--max-rate-hz")) {
            identity.max_rate_hz = strtod(value, NULL);
        } else if (!strcmp(option, "--min-rate-hz")) {
            identity.min_rate_hz = strtod(value, NULL);
        } else {
            usage();
        }
    }
    size_t smallest = IRDAQ_MAX_DATA_FRAME + IRDAQ_FRAME_OVERHEAD + IRDAQ_MAX_REPLY;
    if (!(h->source.speed > 0) || h->source.tach_period < 2 || h->source.tach_width < 1 ||
        h->source.tach_width >= h->source.tach_period || fifo_bytes < smallest ||
        fifo_bytes > sizeof tx_buffer_storage || max_per_frame < 1 ||
        max_per_frame > IRDAQ_MAX_SAMPLES_PER_FRAME) {
        fprintf(stderr, "irdaq-host: a setting is out of range (fifo-bytes %zu..%zu)\n",
                smallest, sizeof tx_buffer_storage);
        return 2;
    }
    if (h->random_state == 0) {
        h->random_state = 1;
    }
    irdaq_hooks hooks = {on_start, NULL, on_skipped};
    irdaq_init(&h->core, &identity, &hooks, h, tx_buffer_storage, fifo_bytes,
               (uint16_t)max_per_frame);
    if (open_pty(h)) {
        return 1;
    }
    for (;;) {
        run_clock(h);
        run_link(h);
        feed_commands(h);
        struct pollfd fds[2] = {{STDIN_FILENO, POLLIN, 0}, {-1, 0, 0}};
        int n_fds = 1;
        if (!h->unplugged) {
            fds[1].fd = h->master;
            fds[1].events = (short)((h->in_length < sizeof h->in ? POLLIN : 0) |
                                    (h->out_sent < h->out_length && !h->stalled ? POLLOUT : 0));
            n_fds = 2;
        }
        int timeout_ms = 50;
        if (h->core.streaming && !h->unplugged) {
            if (isinf(h->source.speed)) {
                bool room = irdaq_ring_free(&h->core.tx) >= irdaq_data_frame_bytes(&h->core);
                timeout_ms = room ? 0 : h->stalled ? 10 : 50;
            } else {
                double wait_ms = 1000.0 * seconds_to_next_frame(h);
                timeout_ms = wait_ms < 50 ? (int)ceil(wait_ms) : 50;
            }
        }
        if (h->in_length && !h->core.reply_pending) {
            timeout_ms = 0;
        }
        if (poll(fds, (nfds_t)n_fds, timeout_ms) < 0 && errno != EINTR) {
            perror("irdaq-host: poll");
            return 1;
        }
        if (fds[0].revents & (POLLIN | POLLHUP)) {
            if (!read_control(h)) {
                break;
            }
        }
        if (n_fds == 2 && (fds[1].revents & POLLIN) && h->in_length < sizeof h->in) {
            ssize_t n = read(h->master, h->in + h->in_length, sizeof h->in - h->in_length);
            if (n > 0) {
                h->in_length += (size_t)n;
            }
        }
    }
    unplug(h);
    return 0;
}
