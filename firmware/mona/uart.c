/* USART0 at 115200 8N1 (U2X; UBRR 8 at 8 MHz, 16 at 16 MHz) with ring buffers. */
#include "uart.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#define UART_BAUD 115200UL
#define RX_SIZE 128 /* powers of two */
#define TX_SIZE 128

static volatile uint8_t rx_buf[RX_SIZE], tx_buf[TX_SIZE];
static volatile uint8_t rx_head, rx_tail, tx_head, tx_tail;
volatile uint16_t uart_rx_overruns;

void uart_init(void) {
    /* Mode before the rate: simavr times the line from these when UBRR0 is written. */
    UCSR0A = _BV(U2X0);
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);
    /* The nearest rate: 8 MHz / (8 * (8 + 1)) = 111111 baud, 3.5 % below 115200 (as the
     * Arduino core's on a Pro Mini 8 MHz: within the receiver's range, not its
     * recommended margin; docs/firmware.md); 16 MHz: 117647, 2.1 % above. */
    UBRR0 = (F_CPU + 4UL * UART_BAUD) / (8UL * UART_BAUD) - 1;
    UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
}

ISR(USART_RX_vect) {
    uint8_t byte = UDR0;
    uint8_t next = (rx_head + 1) & (RX_SIZE - 1);
    if (next == rx_tail) {
        uart_rx_overruns++;
        return;
    }
    rx_buf[rx_head] = byte;
    rx_head = next;
}

ISR(USART_UDRE_vect) {
    if (tx_head == tx_tail) {
        UCSR0B &= (uint8_t)~_BV(UDRIE0);
        return;
    }
    UDR0 = tx_buf[tx_tail];
    tx_tail = (tx_tail + 1) & (TX_SIZE - 1);
}

uint8_t uart_rx_pending(void) { return rx_head != rx_tail; }

int16_t uart_getc(void) {
    if (rx_head == rx_tail)
        return -1;
    uint8_t byte = rx_buf[rx_tail];
    rx_tail = (rx_tail + 1) & (RX_SIZE - 1);
    return byte;
}

uint8_t uart_write(const uint8_t *data, uint8_t len) {
    uint8_t free_bytes = (tx_tail - tx_head - 1) & (TX_SIZE - 1);
    if (len > free_bytes)
        return 0;
    for (uint8_t i = 0; i < len; i++) {
        tx_buf[tx_head] = data[i];
        tx_head = (tx_head + 1) & (TX_SIZE - 1);
    }
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { UCSR0B |= _BV(UDRIE0); }
    return 1;
}
