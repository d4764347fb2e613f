/* A polled USB CDC-ACM device on the STM32F411's OTG_FS core: a serial port to the host. */
#ifndef IRDAQ_USB_CDC_H
#define IRDAQ_USB_CDC_H

#include <stddef.h>
#include <stdint.h>

#include "../core/ring.h"

void usb_cdc_init(void);
/* Service the USB core: enumeration, control requests, finished transfers. */
void usb_cdc_poll(void);
/* Bytes the host sent that the caller has not taken yet (*data: where they are). */
size_t usb_cdc_received(const uint8_t **data);
/* The caller took n of them; when all are taken the next packet may come. */
void usb_cdc_take(size_t n);
/* Send from the ring: starts a transfer of what it holds when the IN endpoint is idle;
 * the bytes leave the ring when the host has them. */
void usb_cdc_send_from(irdaq_ring *tx);

#endif
