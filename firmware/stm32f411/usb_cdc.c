/* USB CDC-ACM on OTG_FS (RM0383 chapter 22), polled from the main loop, no interrupts.
 * Endpoints: 0 control, 1 bulk OUT (commands) and bulk IN (frames), 2 interrupt IN (CDC
 * notifications, never sent).  FIFO RAM (320 words): RX 80, EP0 TX 32, EP1 TX 176, EP2 TX 16. */
#include "usb_cdc.h"

#include <string.h>

#include "regs.h"

#define PACKET 64u
#define IN_MAX 512u /* bytes per bulk IN transfer (8 packets) */

static const uint8_t device_descriptor[18] = {
    18, 1, 0x00, 0x02, 0x02, 0x00, 0x00, 64,
    0x09, 0x12, 0x01, 0x00, /* VID 0x1209 PID 0x0001: pid.codes' test PID, see the guide */
    0x00, 0x01, 1, 2, 3, 1,
};

static const uint8_t configuration_descriptor[67] = {
    9, 2, 67, 0, 2, 1, 0, 0x80, 250, /* 2 interfaces, bus powered, 500 mA */
    /* interface 0: communication class, ACM, AT commands (what every host's driver binds) */
    9, 4, 0, 0, 1, 0x02, 0x02, 0x01, 0,
    5, 0x24, 0x00, 0x10, 0x01,       /* header, CDC 1.10 */
    5, 0x24, 0x01, 0x00, 1,          /* call management: data on interface 1 */
    4, 0x24, 0x02, 0x02,             /* ACM: line coding and serial state */
    5, 0x24, 0x06, 0, 1,             /* union: 0 controls 1 */
    7, 5, 0x82, 0x03, 16, 0, 255,    /* EP2 IN interrupt */
    /* interface 1: data */
    9, 4, 1, 0, 2, 0x0A, 0x00, 0x00, 0,
    7, 5, 0x01, 0x02, 64, 0, 0,      /* EP1 OUT bulk */
    7, 5, 0x81, 0x02, 64, 0, 0,      /* EP1 IN bulk */
};

static const char *const strings[] = {"impact-rig", "IRDAQ-4", "F411-0001"};

static uint8_t setup[8];
static uint8_t ep0_out[PACKET];
static uint8_t line_coding[7] = {0x00, 0xC2, 0x01, 0x00, 0, 0, 8}; /* 115200 8N1 */
static uint8_t pending_request;                                  /* SET_LINE_CODING data */
static uint8_t rx[PACKET];
static size_t rx_length, rx_taken;
static int configured;
static size_t in_length, in_written; /* the bulk IN transfer in flight */
static int in_busy, zlp_due;

static void write_fifo(unsigned endpoint, const uint8_t *data, size_t n)
{
    for (size_t at = 0; at < n; at += 4) {
        uint32_t word = 0;
        memcpy(&word, data + at, n - at < 4 ? n - at : 4);
        OTG_FIFO(endpoint) = word;
    }
}

static void read_fifo(uint8_t *data, size_t n)
{
    for (size_t at = 0; at < n; at += 4) {
        uint32_t word = OTG_FIFO(0);
        memcpy(data + at, &word, n - at < 4 ? n - at : 4);
    }
}

static void ep0_send(const void *data, size_t n)
{
    size_t wanted = (size_t)setup[6] | (size_t)setup[7] << 8;
    if (n > wanted) {
        n = wanted;
    }
    uint32_t packets = n ? (uint32_t)((n + PACKET - 1) / PACKET) : 1u;
    OTG_DIEPTSIZ(0) = packets << 19 | (uint32_t)n;
    OTG_DIEPCTL(0) |= 1u << 31 | 1u << 26; /* EPENA, CNAK */
    write_fifo(0, data, n);
}

static void ep0_arm_out(void)
{
    OTG_DOEPTSIZ(0) = 3u << 29 | 1u << 19 | PACKET; /* 3 setups, 1 packet */
    OTG_DOEPCTL(0) |= 1u << 31 | 1u << 26;
}

static void ep1_arm_out(void)
{
    OTG_DOEPTSIZ(1) = 1u << 19 | PACKET;
    OTG_DOEPCTL(1) |= 1u << 31 | 1u << 26;
}

static void send_string(unsigned index)
{
    uint8_t descriptor[64];
    if (index == 0) {
        const uint8_t languages[4] = {4, 3, 0x09, 0x04};
        ep0_send(languages, sizeof languages);
        return;
    }
    if (index > 3) {
        OTG_DIEPCTL(0) |= 1u << 21; /* STALL */
        return;
    }
    const char *text = strings[index - 1];
    size_t n = strlen(text);
    descriptor[0] = (uint8_t)(2 + 2 * n);
    descriptor[1] = 3;
    for (size_t k = 0; k < n; k++) {
        descriptor[2 + 2 * k] = (uint8_t)text[k];
        descriptor[3 + 2 * k] = 0;
    }
    ep0_send(descriptor, descriptor[0]);
}

static void configure_endpoints(void)
{
    OTG_DIEPCTL(1) = 1u << 28 | 1u << 22 | 2u << 18 | 1u << 15 | PACKET; /* bulk, FIFO 1 */
    OTG_DIEPCTL(2) = 1u << 28 | 2u << 22 | 3u << 18 | 1u << 15 | 16u;    /* interrupt */
    OTG_DOEPCTL(1) = 1u << 28 | 2u << 18 | 1u << 15 | PACKET;
    rx_length = rx_taken = 0;
    in_busy = zlp_due = 0;
    ep1_arm_out();
    configured = 1;
}

static void handle_setup(void)
{
    uint8_t type = setup[0], request = setup[1];
    uint16_t value = (uint16_t)(setup[2] | setup[3] << 8);
    ep0_arm_out(); /* the status stage (or the next setup) may come */
    if (type == 0x80 && request == 6) { /* GET_DESCRIPTOR */
        switch (value >> 8) {
        case 1: ep0_send(device_descriptor, sizeof device_descriptor); return;
        case 2: ep0_send(configuration_descriptor, sizeof configuration_descriptor); return;
        case 3: send_string(value & 0xFFu); return;
        default: OTG_DIEPCTL(0) |= 1u << 21; return;
        }
    }
    if (type == 0x00 && request == 5) { /* SET_ADDRESS: this core takes it before the status */
        OTG_DCFG = (OTG_DCFG & ~(0x7Fu << 4)) | (uint32_t)(value & 0x7Fu) << 4;
        ep0_send(NULL, 0);
    } else if (type == 0x00 && request == 9) { /* SET_CONFIGURATION */
        configure_endpoints();
        ep0_send(NULL, 0);
    } else if (type == 0x80 && request == 0) { /* GET_STATUS */
        const uint8_t status[2] = {0, 0};
        ep0_send(status, 2);
    } else if (type == 0x21 && request == 0x20) { /* SET_LINE_CODING: 7 bytes follow */
        pending_request = request;
    } else if (type == 0xA1 && request == 0x21) { /* GET_LINE_CODING */
        ep0_send(line_coding, sizeof line_coding);
    } else if (type == 0x21 && (request == 0x22 || request == 0x23)) { /* lines, break */
        ep0_send(NULL, 0);
    } else {
        OTG_DIEPCTL(0) |= 1u << 21;
    }
}

static void bus_reset(void)
{
    for (unsigned n = 0; n < 4; n++) {
        OTG_DOEPCTL(n) |= 1u << 27; /* SNAK */
    }
    OTG_DAINTMSK = 0x00070007u;
    OTG_DOEPMSK = 1u << 3 | 1u << 0; /* STUP, XFRC */
    OTG_DIEPMSK = 1u << 0;
    OTG_DCFG &= ~(0x7Fu << 4);
    configured = 0;
    ep0_arm_out();
}

void usb_cdc_init(void)
{
    RCC_AHB1ENR |= 1u << 0;  /* GPIOA */
    RCC_AHB2ENR |= 1u << 7;  /* OTG_FS */
    GPIOA_MODER = (GPIOA_MODER & ~(0xFu << 22)) | 0xAu << 22;          /* PA11, PA12: AF */
    GPIOA_OSPEEDR |= 0xFu << 22;
    GPIOA_AFRH = (GPIOA_AFRH & ~(0xFFu << 12)) | 0xAAu << 12;          /* AF10: OTG_FS */
    OTG_GUSBCFG |= 1u << 6;                                            /* PHYSEL */
    while (!(OTG_GRSTCTL & 1u << 31)) { /* AHB idle */
    }
    OTG_GRSTCTL |= 1u; /* core soft reset */
    while (OTG_GRSTCTL & 1u) {
    }
    OTG_GUSBCFG = (OTG_GUSBCFG & ~(0xFu << 10)) | 6u << 10 | 1u << 30 | 1u << 6; /* TRDT, FDMOD */
    for (volatile uint32_t wait = 0; wait < 600000u; wait++) { /* 25 ms: device mode */
    }
    OTG_GCCFG = 1u << 16 | 1u << 21; /* PHY on, no VBUS sensing (PA9 is not wired) */
    OTG_PCGCCTL = 0;
    OTG_DCTL |= 1u << 1;  /* soft disconnect while configuring */
    OTG_DCFG |= 3u;       /* full speed */
    OTG_GRXFSIZ = 80;
    OTG_DIEPTXF0 = 32u << 16 | 80u;
    OTG_DIEPTXF(1) = 176u << 16 | 112u;
    OTG_DIEPTXF(2) = 16u << 16 | 288u;
    OTG_GRSTCTL = 0x10u << 6 | 1u << 5; /* flush every TX FIFO */
    while (OTG_GRSTCTL & 1u << 5) {
    }
    OTG_GRSTCTL = 1u << 4; /* flush the RX FIFO */
    while (OTG_GRSTCTL & 1u << 4) {
    }
    OTG_GINTMSK = 0; /* polled: nothing interrupts */
    OTG_GINTSTS = 0xFFFFFFFFu;
    OTG_DCTL &= ~(1u << 1); /* connect */
}

static void receive_packets(void)
{
    while (OTG_GINTSTS & 1u << 4) { /* RXFLVL */
        uint32_t status = OTG_GRXSTSP;
        unsigned endpoint = status & 0xFu;
        size_t count = status >> 4 & 0x7FFu;
        unsigned kind = status >> 17 & 0xFu;
        if (kind == 6) { /* SETUP packet */
            read_fifo(setup, 8);
        } else if (kind == 2 && endpoint == 1) { /* commands */
            uint8_t scratch[PACKET];
            size_t n = count > PACKET ? PACKET : count;
            read_fifo(scratch, n);
            memcpy(rx + rx_length, scratch, n <= PACKET - rx_length ? n : PACKET - rx_length);
            rx_length += n <= PACKET - rx_length ? n : PACKET - rx_length;
        } else if (kind == 2) {
            read_fifo(ep0_out, count > PACKET ? PACKET : count);
        }
    }
}

void usb_cdc_poll(void)
{
    uint32_t events = OTG_GINTSTS;
    if (events & 1u << 12) { /* USBRST */
        OTG_GINTSTS = 1u << 12;
        bus_reset();
    }
    if (events & 1u << 13) { /* ENUMDNE: EP0 takes 64-byte packets */
        OTG_GINTSTS = 1u << 13;
        OTG_DIEPCTL(0) &= ~3u;
    }
    receive_packets();
    uint32_t out0 = OTG_DOEPINT(0);
    if (out0 & 1u << 3) { /* STUP */
        OTG_DOEPINT(0) = 1u << 3;
        handle_setup();
    }
    if (out0 & 1u) { /* XFRC: a control OUT data stage */
        OTG_DOEPINT(0) = 1u;
        if (pending_request == 0x20) {
            memcpy(line_coding, ep0_out, sizeof line_coding);
            pending_request = 0;
            ep0_send(NULL, 0);
        }
        ep0_arm_out();
    }
    if (OTG_DIEPINT(0) & 1u) {
        OTG_DIEPINT(0) = 1u;
    }
    if (OTG_DOEPINT(1) & 1u) { /* a command packet is in rx: re-armed once all is taken */
        OTG_DOEPINT(1) = 1u;
    }
}

size_t usb_cdc_received(const uint8_t **data)
{
    *data = rx + rx_taken;
    return rx_length - rx_taken;
}

void usb_cdc_take(size_t n)
{
    rx_taken += n;
    if (configured && rx_taken == rx_length && rx_length) {
        rx_length = rx_taken = 0;
        ep1_arm_out();
    }
}

void usb_cdc_send_from(irdaq_ring *tx)
{
    if (!configured) {
        return;
    }
    if (in_busy) {
        if (in_written < in_length) { /* fill the FIFO a packet at a time as room appears */
            const uint8_t *data;
            irdaq_ring_contiguous(tx, &data);
            size_t chunk = in_length - in_written < PACKET ? in_length - in_written : PACKET;
            if ((OTG_DTXFSTS(1) & 0xFFFFu) * 4u >= chunk) {
                write_fifo(1, data + in_written, chunk);
                in_written += chunk;
            }
        }
        if (OTG_DIEPINT(1) & 1u) { /* XFRC: the host has it */
            OTG_DIEPINT(1) = 1u;
            irdaq_ring_consume(tx, in_length);
            zlp_due = in_length && in_length % PACKET == 0;
            in_busy = 0;
        }
        return;
    }
    const uint8_t *data;
    size_t n = irdaq_ring_contiguous(tx, &data);
    if (n == 0 && !zlp_due) {
        return;
    }
    n = n > IN_MAX ? IN_MAX : n;
    uint32_t packets = n ? (uint32_t)((n + PACKET - 1) / PACKET) : 1u; /* 0: a ZLP ends it */
    zlp_due = 0;
    in_length = n;
    in_written = 0;
    in_busy = 1;
    OTG_DIEPTSIZ(1) = packets << 19 | (uint32_t)n;
    OTG_DIEPCTL(1) |= 1u << 31 | 1u << 26;
}
