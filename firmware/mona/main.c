/*
 * Mona firmware: the Mona link v1 (docs/design.md#mona-link) over the UART, driving the wheel motors.
 *
 * HELLO at boot and every second until the first valid frame; WHEELS drives the motors
 * until its timeout passes without another (the command watchdog); STOP stops them;
 * PING answers PONG; TELEMETRY at 20 Hz and after every WHEELS and STOP. A frame that
 * fails COBS, length, version or CRC, or whose type or body length is wrong, is
 * dropped and changes nothing. The AVR watchdog resets a hung MCU; between events the
 * MCU sleeps (SLEEP_MODE_IDLE). docs/firmware.md has the build and the pin map.
 */
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <avr/wdt.h>
#include <util/atomic.h>

#include "link.h"
#include "motors.h"
#include "pins.h"
#include "sensors.h"
#include "uart.h"

#define FW_MAJOR 1
#define FW_MINOR 0
#define HELLO_PERIOD_MS 1000
#define TELEMETRY_PERIOD_MS 50

#define FLAG_STOPPED_BY_TIMEOUT 0x01
#define FLAG_STOPPED_BY_STOP 0x02
#define FLAG_BATTERY_LOW 0x04

/* The robot id lives in EEPROM byte 0; erased (0xFF), it is ROBOT_ID of the build. */
#define EEPROM_ROBOT_ID ((const uint8_t *)0)
#ifndef ROBOT_ID
#define ROBOT_ID 0
#endif

static volatile uint32_t ticks_ms;

static uint8_t robot_id;
static uint16_t tx_seq;       /* one counter over every frame sent */
static uint16_t ack_seq;      /* last WHEELS/STOP applied */
static uint8_t flags;
static uint8_t heard;         /* a valid frame arrived: HELLO stops */
static uint8_t driving;
static uint32_t wheels_at_ms;
static uint16_t wheels_timeout_ms;
static int16_t applied_left, applied_right;

static struct link_rx rx;

/* Counted, not reported: docs/design.md#mona-link TELEMETRY has no field for them. */
static uint16_t dropped_frames, tx_dropped;

/* The AVR watchdog stays on after a watchdog reset: turn it off before main. */
void early_wdt_off(void) __attribute__((naked, used, section(".init3")));
void early_wdt_off(void) {
    MCUSR = 0;
    wdt_disable();
}

ISR(TIMER0_COMPA_vect) { ticks_ms++; }

static uint32_t now_ms(void) {
    uint32_t t;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { t = ticks_ms; }
    return t;
}

static void clock_init(void) {
    TCCR0A = _BV(WGM01);            /* CTC */
    TCCR0B = _BV(CS01) | _BV(CS00); /* clk/64 */
    OCR0A = F_CPU / 64 / 1000 - 1;  /* 1 kHz: 124 at 8 MHz, 249 at 16 MHz */
    TIMSK0 = _BV(OCIE0A);
}

static void send(uint8_t type, const uint8_t *body, uint8_t body_len) {
    uint8_t frame[LINK_MAX_ENCODED + 1];
    uint8_t len = link_encode(type, tx_seq, body, body_len, frame);
    if (uart_write(frame, len))
        tx_seq++;
    else
        tx_dropped++;
}

static void send_hello(void) {
    uint8_t body[11] = {robot_id, FW_MAJOR, FW_MINOR, 'm', 'o', 'n', 'a', '3', '2', '8', 0};
    send(MSG_HELLO, body, sizeof body);
}

static void send_telemetry(void) {
    uint8_t body[2 + 2 + 2 + 2 * IR_COUNT + 2 + 1];
    uint16_t ir[IR_COUNT], battery_mv;
    sensors_latest(ir, &battery_mv);
    if (battery_mv < BATTERY_LOW_MV)
        flags |= FLAG_BATTERY_LOW;
    else
        flags &= (uint8_t)~FLAG_BATTERY_LOW;
    put_u16(body, ack_seq);
    put_u16(body + 2, (uint16_t)applied_left);
    put_u16(body + 4, (uint16_t)applied_right);
    for (uint8_t i = 0; i < IR_COUNT; i++)
        put_u16(body + 6 + 2 * i, ir[i]);
    put_u16(body + 6 + 2 * IR_COUNT, battery_mv);
    body[8 + 2 * IR_COUNT] = flags;
    send(MSG_TELEMETRY, body, sizeof body);
}

static void stop_motors(uint8_t why) {
    motors_off();
    applied_left = applied_right = 0;
    driving = 0;
    flags |= why;
}

static void handle(const struct link_frame *frame) {
    switch (frame->type) {
    case MSG_WHEELS:
        if (frame->body_len != 6)
            break;
        applied_left = (int16_t)get_u16(frame->body);
        applied_right = (int16_t)get_u16(frame->body + 2);
        wheels_timeout_ms = get_u16(frame->body + 4);
        motors_set(&applied_left, &applied_right);
        wheels_at_ms = now_ms();
        driving = 1;
        flags &= (uint8_t)~(FLAG_STOPPED_BY_TIMEOUT | FLAG_STOPPED_BY_STOP);
        ack_seq = frame->seq;
        heard = 1;
        send_telemetry();
        return;
    case MSG_STOP:
        if (frame->body_len != 0)
            break;
        stop_motors(FLAG_STOPPED_BY_STOP);
        ack_seq = frame->seq;
        heard = 1;
        send_telemetry();
        return;
    case MSG_PING:
        if (frame->body_len != 0)
            break;
        {
            uint8_t body[2];
            put_u16(body, frame->seq);
            heard = 1;
            send(MSG_PONG, body, sizeof body);
        }
        return;
    default:
        break;
    }
    dropped_frames++; /* a type the robot does not take, or a body of the wrong length */
}

static void receive(uint8_t byte) {
    uint8_t payload[LINK_MAX_PAYLOAD];
    struct link_frame frame;
    int result = link_receive(&rx, byte, payload, &frame);
    if (result == LINK_OK)
        handle(&frame);
    else if (result != LINK_RX_NONE)
        dropped_frames++;
}

int main(void) {
    robot_id = eeprom_read_byte(EEPROM_ROBOT_ID);
    if (robot_id == 0xFF)
        robot_id = ROBOT_ID;
    LED_DDR |= _BV(LED_TOP_BIT);
    motors_init();
    sensors_init();
    uart_init();
    clock_init();
    set_sleep_mode(SLEEP_MODE_IDLE);
    sei();
    wdt_enable(WDTO_250MS);

    uint32_t hello_due = now_ms();
    uint32_t telemetry_due = hello_due + TELEMETRY_PERIOD_MS;
    sensors_start_scan();
    for (;;) {
        wdt_reset();
        int16_t byte;
        while ((byte = uart_getc()) >= 0)
            receive((uint8_t)byte);

        uint32_t now = now_ms();
        if (driving && now - wheels_at_ms >= wheels_timeout_ms)
            stop_motors(FLAG_STOPPED_BY_TIMEOUT);
        if (!heard && (int32_t)(now - hello_due) >= 0) {
            send_hello();
            hello_due += HELLO_PERIOD_MS;
        }
        if ((int32_t)(now - telemetry_due) >= 0) {
            send_telemetry();
            sensors_start_scan();
            telemetry_due += TELEMETRY_PERIOD_MS;
            if ((int32_t)(now - telemetry_due) >= 0) /* fell behind: no burst */
                telemetry_due = now + TELEMETRY_PERIOD_MS;
        }
        if (driving)
            LED_PORT |= _BV(LED_TOP_BIT);
        else
            LED_PORT &= (uint8_t)~_BV(LED_TOP_BIT);

        /* Sleep until the next interrupt (the 1 ms tick at the latest); the check
         * and the sleep are atomic, so a byte arriving in between still wakes it. */
        cli();
        if (!uart_rx_pending()) {
            sleep_enable();
            sei();
            sleep_cpu();
            sleep_disable();
        }
        sei();
    }
}
