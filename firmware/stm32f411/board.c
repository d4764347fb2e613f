/* The IRDAQ-4 on an STM32F411CE "Black Pill": clocks, the sample clock, the ADC, the loop.
 *
 * Sample clock: TIM2 counts a 10 MHz tick (60 MHz / 6) and overflows every `divider`
 * ticks; each overflow (TRGO) starts one scan of ADC1 over the enabled inputs (PA0..PA3,
 * ascending) and the tach (PA4), and DMA2 stream 0 copies the conversions into a circular
 * buffer.  No CPU is involved per sample; the main loop turns whole sample instants of
 * that buffer into frames (irdaq_push_sample), feeds USB command bytes to the core and
 * sends the core's FIFO over USB.  Polled throughout: no interrupts.
 *
 * Counts: the 12-bit conversion r (0..4095 over 0..3.3 V) becomes the protocol's 16-bit
 * word by bit replication, (r << 4 | r >> 8) - 32768: 0 V reads -32768 and 3.3 V reads
 * 32767, the rails the host flags.  The tach bit is 1 when PA4 is above half of 3.3 V.
 */
#include <stdint.h>

#include "../core/irdaq.h"
#include "regs.h"
#include "usb_cdc.h"

#define TACH_INPUT 4u
#define DMA_INSTANTS 1024u /* sample instants the DMA buffer holds (at 250 kHz: 4 ms) */

static uint16_t conversions[DMA_INSTANTS * (IRDAQ_MAX_CHANNELS + 1)];
static uint8_t tx_storage[64u * 1024u];
static irdaq_core core;

static uint32_t per_instant;   /* conversions per sample instant: inputs + tach */
static uint32_t buffer_words;  /* DMA_INSTANTS * per_instant */
static uint32_t laps;          /* DMA wrap-arounds seen */
static uint64_t consumed;      /* conversions taken from the buffer since START */

static void clocks_init(void)
{
    RCC_CR |= 1u << 16; /* HSE: the board's 25 MHz crystal */
    while (!(RCC_CR & 1u << 17)) {
    }
    /* PLL: 25 MHz / 25 * 240 = 240 MHz VCO; / 4 = 60 MHz system; / 5 = 48 MHz USB.
     * 60 MHz is a multiple of the protocol's 10 MHz sample clock: TIM2 gets it exactly. */
    RCC_PLLCFGR = 25u | 240u << 6 | 1u << 16 | 1u << 22 | 5u << 24;
    RCC_CR |= 1u << 24;
    while (!(RCC_CR & 1u << 25)) {
    }
    FLASH_ACR = 1u | 1u << 8 | 1u << 9 | 1u << 10; /* 1 wait state, prefetch, caches */
    RCC_CFGR = 4u << 10 | 2u;                      /* APB1 = 30 MHz (timers 60), PLL on */
    while ((RCC_CFGR >> 2 & 3u) != 2u) {
    }
}

static void analog_init(void)
{
    RCC_AHB1ENR |= 1u << 0 | 1u << 22; /* GPIOA, DMA2 */
    RCC_APB1ENR |= 1u << 0;            /* TIM2 */
    RCC_APB2ENR |= 1u << 8;            /* ADC1 */
    GPIOA_MODER |= 0x3FFu;             /* PA0..PA4 analog */
    ADC_CCR &= ~(3u << 16);            /* ADC clock 60 / 2 = 30 MHz */
}

/* The longest ADC sampling time whose scan fits in 80 % of a sample period. */
static uint32_t sampling_code(uint32_t divider, uint32_t n_conversions)
{
    static const uint16_t cycles[8] = {3, 15, 28, 56, 84, 112, 144, 480};
    uint32_t code = 0;
    for (uint32_t k = 0; k < 8; k++) {
        /* scan time in ADC cycles (30 MHz) against 0.8 * divider / 10 MHz = 2.4 * divider */
        if (n_conversions * (cycles[k] + 12u) * 10u <= divider * 24u) {
            code = k;
        }
    }
    return code;
}

static void sampling_start(void *context, const irdaq_config *config)
{
    (void)context;
    TIM2_CR1 = 0;
    ADC1_CR2 = 0;
    DMA2_S0CR = 0;
    while (DMA2_S0CR & 1u) {
    }
    per_instant = config->n_analog + 1u;
    buffer_words = DMA_INSTANTS * per_instant;
    uint32_t sequence = 0, smp = sampling_code(config->divider, per_instant), smpr = 0;
    for (uint32_t k = 0; k < per_instant; k++) {
        uint32_t input = k < config->n_analog ? config->channels[k] : TACH_INPUT;
        sequence |= input << (5u * k);
    }
    for (uint32_t input = 0; input <= TACH_INPUT; input++) {
        smpr |= smp << (3u * input);
    }
    ADC1_SMPR2 = smpr;
    ADC1_SQR1 = (per_instant - 1u) << 20;
    ADC1_SQR3 = sequence;
    ADC1_CR1 = 1u << 8; /* scan, 12 bits */
    DMA2_LIFCR = 0x3Du;
    DMA2_S0PAR = ADC1_DR_ADDRESS;
    DMA2_S0M0AR = (uint32_t)(uintptr_t)conversions;
    DMA2_S0NDTR = buffer_words;
    DMA2_S0CR = 1u << 13 | 1u << 11 | 1u << 10 | 1u << 8 | 1u; /* 16 bit, MINC, CIRC, EN */
    ADC1_SR = 0;
    ADC1_CR2 = 1u | 1u << 8 | 1u << 9 | 6u << 24 | 1u << 28; /* on, DMA, DDS, TIM2 TRGO */
    TIM2_PSC = 5u;                    /* 60 MHz / 6 = 10 MHz */
    TIM2_ARR = config->divider - 1u;
    TIM2_CR2 = 2u << 4;               /* TRGO on update */
    TIM2_EGR = 1u;                    /* load PSC (no trigger yet: the ADC ignores it) */
    TIM2_CNT = 0;
    laps = 0;
    consumed = 0;
    TIM2_CR1 = 1u; /* sample 0 comes one period from now */
}

static void sampling_stop(void *context)
{
    (void)context;
    TIM2_CR1 = 0;
    ADC1_CR2 = 0;
    DMA2_S0CR = 0;
}

static int16_t to_counts(uint16_t raw)
{
    return (int16_t)((int32_t)((uint32_t)raw << 4 | (uint32_t)raw >> 8) - 32768);
}

/* Hand the sample instants the DMA has finished to the core (or their loss, if lapped). */
static void collect_samples(void)
{
    if (!core.streaming) {
        return;
    }
    uint32_t remaining, flags;
    do {
        flags = DMA2_LISR & (1u << 5);
        remaining = DMA2_S0NDTR;
    } while (flags != (DMA2_LISR & (1u << 5)));
    if (flags) {
        DMA2_LIFCR = 1u << 5;
        laps++;
        if (remaining == buffer_words) { /* wrapped exactly: NDTR reloaded */
            remaining = buffer_words;
        }
    }
    uint64_t written = (uint64_t)laps * buffer_words + (buffer_words - remaining);
    if (written - consumed > buffer_words - per_instant) { /* the DMA overtook us */
        uint64_t behind = (written - consumed) / per_instant - (DMA_INSTANTS - 1u);
        irdaq_lose_samples(&core, (uint32_t)behind);
        consumed += behind * per_instant;
    }
    int16_t analog[IRDAQ_MAX_CHANNELS];
    while (written - consumed >= per_instant && core.streaming) {
        uint32_t at = (uint32_t)(consumed % buffer_words);
        for (uint32_t k = 0; k + 1u < per_instant; k++) {
            analog[k] = to_counts(conversions[at + k]);
        }
        uint16_t tach = conversions[at + per_instant - 1u] >= 2048u ? 1u : 0u;
        irdaq_push_sample(&core, analog, tach);
        consumed += per_instant;
    }
}

int main(void)
{
    static const irdaq_identity identity = {
        "IRDAQ-4", "F411-0001", IRDAQ_FIRMWARE_VERSION, 10.0, 250000.0, 16, 10.0,
    };
    static const irdaq_hooks hooks = {sampling_start, sampling_stop, NULL};
    clocks_init();
    analog_init();
    irdaq_init(&core, &identity, &hooks, NULL, tx_storage, sizeof tx_storage,
               IRDAQ_MAX_SAMPLES_PER_FRAME);
    usb_cdc_init();
    for (;;) {
        usb_cdc_poll();
        const uint8_t *data;
        size_t n = usb_cdc_received(&data);
        if (n) {
            usb_cdc_take(irdaq_receive(&core, data, n));
        }
        collect_samples();
        usb_cdc_send_from(&core.tx);
        irdaq_poll(&core);
    }
}
