/* The two wheel motors: Timer1 PWM duty and a direction pin each. */
#ifndef MONA_MOTORS_H
#define MONA_MOTORS_H

#include <stdint.h>

/* Wheel rim speed at full duty [mm/s]: 9 rad/s × 15 mm (docs/design.md#mona). */
#define MOTOR_MAX_MM_S 135

void motors_init(void);
/* Drive at rim speeds [mm/s], clamped to ±MOTOR_MAX_MM_S; returns them clamped. */
void motors_set(int16_t *left_mm_s, int16_t *right_mm_s);
void motors_off(void);

#endif
