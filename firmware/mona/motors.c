/* Wheel motors: Timer1 fast PWM 8-bit (488 Hz at 8 MHz) on OC1A/OC1B, direction on PD6/PD5. */
#include "motors.h"

#include <avr/io.h>

#include "pins.h"

void motors_init(void) {
    MOTOR_PWM_PORT &= (uint8_t)~(_BV(MOTOR_LEFT_PWM_BIT) | _BV(MOTOR_RIGHT_PWM_BIT));
    MOTOR_PWM_DDR |= _BV(MOTOR_LEFT_PWM_BIT) | _BV(MOTOR_RIGHT_PWM_BIT);
    MOTOR_DIR_PORT &= (uint8_t)~(_BV(MOTOR_LEFT_DIR_BIT) | _BV(MOTOR_RIGHT_DIR_BIT));
    MOTOR_DIR_DDR |= _BV(MOTOR_LEFT_DIR_BIT) | _BV(MOTOR_RIGHT_DIR_BIT);
    TCCR1A = _BV(WGM10);                           /* fast PWM, 8-bit (mode 5) */
    TCCR1B = _BV(WGM12) | _BV(CS11) | _BV(CS10);   /* clk/64: F_CPU / 64 / 256 */
    motors_off();
}

static int16_t clamp(int16_t v) {
    if (v > MOTOR_MAX_MM_S)
        return MOTOR_MAX_MM_S;
    if (v < -MOTOR_MAX_MM_S)
        return -MOTOR_MAX_MM_S;
    return v;
}

static uint8_t duty(int16_t mm_s) {
    uint16_t speed = (uint16_t)(mm_s < 0 ? -mm_s : mm_s);
    return (uint8_t)((speed * 255u + MOTOR_MAX_MM_S / 2) / MOTOR_MAX_MM_S);
}

/* A duty of 0 disconnects the output: fast PWM would still pulse once per period. */
static void drive(uint8_t left_duty, uint8_t left_reverse, uint8_t right_duty,
                  uint8_t right_reverse) {
    uint8_t dir = MOTOR_DIR_PORT & (uint8_t)~(_BV(MOTOR_LEFT_DIR_BIT) | _BV(MOTOR_RIGHT_DIR_BIT));
    if (left_reverse)
        dir |= _BV(MOTOR_LEFT_DIR_BIT);
    if (right_reverse)
        dir |= _BV(MOTOR_RIGHT_DIR_BIT);
    MOTOR_DIR_PORT = dir;
    OCR1A = left_duty;
    OCR1B = right_duty;
    uint8_t com = TCCR1A & (uint8_t)~(_BV(COM1A1) | _BV(COM1B1));
    if (left_duty)
        com |= _BV(COM1A1);
    if (right_duty)
        com |= _BV(COM1B1);
    TCCR1A = com;
}

void motors_set(int16_t *left_mm_s, int16_t *right_mm_s) {
    *left_mm_s = clamp(*left_mm_s);
    *right_mm_s = clamp(*right_mm_s);
    drive(duty(*left_mm_s), *left_mm_s < 0, duty(*right_mm_s), *right_mm_s < 0);
}

void motors_off(void) { drive(0, 0, 0, 0); }
