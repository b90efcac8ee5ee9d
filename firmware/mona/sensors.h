/* IR proximity and battery readings, scanned by the ADC interrupt. */
#ifndef MONA_SENSORS_H
#define MONA_SENSORS_H

#include <stdint.h>

#define IR_COUNT 5
/* Battery [mV] at a full-scale reading: AVcc 5 V through a 1:2 divider (an assumption:
 * calibrate against a voltmeter, docs/firmware.md). */
#define BATTERY_FULL_SCALE_MV 10000UL
/* Below this the TELEMETRY flag "battery low" is set (one Li-ion cell). */
#define BATTERY_LOW_MV 3400

void sensors_init(void);
/* Start one scan of the five IR channels and the battery; returns at once. */
void sensors_start_scan(void);
/* The last complete scan: raw IR readings in TELEMETRY order, battery [mV]. */
void sensors_latest(uint16_t ir[IR_COUNT], uint16_t *battery_mv);

#endif
