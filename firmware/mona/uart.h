/* USART0 at 115200 8N1 with interrupt-driven receive and transmit ring buffers. */
#ifndef MONA_UART_H
#define MONA_UART_H

#include <stdint.h>

void uart_init(void);
/* The next received byte, or -1 when none is waiting. */
int16_t uart_getc(void);
uint8_t uart_rx_pending(void);
/* Queue `len` bytes whole; 0 (and nothing queued) when they do not fit. */
uint8_t uart_write(const uint8_t *data, uint8_t len);
/* Bytes lost because the receive buffer was full. */
extern volatile uint16_t uart_rx_overruns;

#endif
