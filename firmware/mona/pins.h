/*
 * Pin map of the original Mona (ATmega328P).
 *
 * Source: github.com/Farshad-Arvin/Mona-Platform (MonaRobot's "basic functions and test
 * code in Arduino", www.monarobot.uk), the "pin config for basic platform test" of
 * Mona-Test.ino and Mona-Motion-Control.ino: Motor_right_PWM = 10,
 * Motor_right_direction = 5, Motor_left_PWM = 9, Motor_left_direction = 6
 * ("0 Forward - 1 Reverse"), LED1 = 13 (top), LED2 = 12, IR_enable = 4, IR on A3 right,
 * A2 right-front, A1 front, A0 left-front, A7 left; the battery on A6 from
 * bird43/MonaMk2, MONA.h (Ben Bird, a Mona co-author). docs/firmware.md lists them with
 * the clock (8 MHz, from the same README); check them against your board
 * before flashing.
 */
#ifndef MONA_PINS_H
#define MONA_PINS_H

#include <avr/io.h>

/* Motor PWM: Arduino D9 = PB1 = OC1A (left), D10 = PB2 = OC1B (right), Timer1. */
#define MOTOR_PWM_DDR DDRB
#define MOTOR_PWM_PORT PORTB
#define MOTOR_LEFT_PWM_BIT PB1
#define MOTOR_RIGHT_PWM_BIT PB2
/* Motor direction: Arduino D6 = PD6 (left), D5 = PD5 (right); high = reverse. */
#define MOTOR_DIR_DDR DDRD
#define MOTOR_DIR_PORT PORTD
#define MOTOR_LEFT_DIR_BIT PD6
#define MOTOR_RIGHT_DIR_BIT PD5

/* IR emitters: Arduino D4 = PD4, high while the IR sensors are read. */
#define IR_ENABLE_DDR DDRD
#define IR_ENABLE_PORT PORTD
#define IR_ENABLE_BIT PD4

/* ADC channels in TELEMETRY's sensor order 0°, +37°, −37°, +67°, −67° (CCW positive):
 * front A1, left-front A0, right-front A2, left A7, right A3. */
#define IR_CHANNELS {1, 0, 2, 7, 3}
/* Battery: A6, through a divider (see BATTERY_FULL_SCALE_MV in sensors.h). */
#define BATTERY_CHANNEL 6

/* LEDs: Arduino D13 = PB5 (top), D12 = PB4. */
#define LED_DDR DDRB
#define LED_PORT PORTB
#define LED_TOP_BIT PB5

#endif
