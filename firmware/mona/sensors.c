/* ADC scan of the IR sensors and the battery, one conversion per ADC interrupt. */
#include "sensors.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#include "pins.h"

static const uint8_t ir_channels[IR_COUNT] = IR_CHANNELS;
static volatile uint16_t scanning[IR_COUNT + 1], latest[IR_COUNT + 1];
static volatile uint8_t index_ = IR_COUNT + 1; /* > IR_COUNT: idle */

static void start(uint8_t i) {
    /* AVcc reference */
    ADMUX = _BV(REFS0) | (i < IR_COUNT ? ir_channels[i] : BATTERY_CHANNEL);
    ADCSRA |= _BV(ADSC);
}

void sensors_init(void) {
    IR_ENABLE_DDR |= _BV(IR_ENABLE_BIT);
    IR_ENABLE_PORT &= (uint8_t)~_BV(IR_ENABLE_BIT);
    /* enabled, interrupt, clk/128 = 125 kHz */
    ADCSRA = _BV(ADEN) | _BV(ADIE) | _BV(ADPS2) | _BV(ADPS1) | _BV(ADPS0);
}

void sensors_start_scan(void) {
    if (index_ <= IR_COUNT)
        return; /* the previous scan is still running */
    IR_ENABLE_PORT |= _BV(IR_ENABLE_BIT);
    index_ = 0;
    start(0);
}

ISR(ADC_vect) {
    scanning[index_] = ADC;
    if (++index_ <= IR_COUNT) {
        if (index_ == IR_COUNT)
            IR_ENABLE_PORT &= (uint8_t)~_BV(IR_ENABLE_BIT);
        start(index_);
        return;
    }
    for (uint8_t i = 0; i <= IR_COUNT; i++)
        latest[i] = scanning[i];
}

void sensors_latest(uint16_t ir[IR_COUNT], uint16_t *battery_mv) {
    uint16_t battery_raw;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        for (uint8_t i = 0; i < IR_COUNT; i++)
            ir[i] = latest[i];
        battery_raw = latest[IR_COUNT];
    }
    *battery_mv = (uint16_t)((battery_raw * BATTERY_FULL_SCALE_MV + 511) / 1023);
}
