/* Mona link v1 framing (docs/design.md#mona-link); plain C, no AVR registers. */
#include "link.h"

uint16_t link_crc16(const uint8_t *data, uint8_t len) {
    uint16_t crc = 0xFFFF; /* CCITT-FALSE: poly 0x1021, no reflection, no xor-out */
    while (len--) {
        crc ^= (uint16_t)(*data++) << 8;
        for (uint8_t bit = 0; bit < 8; bit++)
            crc = (crc & 0x8000) ? (uint16_t)((crc << 1) ^ 0x1021) : (uint16_t)(crc << 1);
    }
    return crc;
}

enum link_error link_decode(const uint8_t *encoded, uint8_t len, uint8_t *payload,
                            struct link_frame *frame) {
    uint8_t in = 0, out = 0;
    if (len > LINK_MAX_ENCODED)
        return LINK_ERR_LENGTH;
    while (in < len) {
        uint8_t code = encoded[in++];
        if (code == 0)
            return LINK_ERR_COBS;
        for (uint8_t k = 1; k < code; k++) {
            if (in >= len || encoded[in] == 0)
                return LINK_ERR_COBS;
            if (out >= LINK_MAX_PAYLOAD)
                return LINK_ERR_LENGTH;
            payload[out++] = encoded[in++];
        }
        if (code != 0xFF && in < len) {
            if (out >= LINK_MAX_PAYLOAD)
                return LINK_ERR_LENGTH;
            payload[out++] = 0;
        }
    }
    if (out < LINK_MIN_PAYLOAD)
        return LINK_ERR_LENGTH;
    if (payload[0] != LINK_VERSION)
        return LINK_ERR_VERSION;
    if (link_crc16(payload, out - 2) != get_u16(payload + out - 2))
        return LINK_ERR_CRC;
    frame->type = payload[1];
    frame->seq = get_u16(payload + 2);
    frame->body = payload + LINK_HEADER;
    frame->body_len = out - LINK_MIN_PAYLOAD;
    return LINK_OK;
}

int link_receive(struct link_rx *rx, uint8_t byte, uint8_t *payload, struct link_frame *frame) {
    if (byte != 0) {
        if (rx->skipping)
            return LINK_RX_NONE;
        if (rx->len == sizeof rx->encoded) {
            rx->skipping = 1;
            rx->len = 0;
            return LINK_ERR_LENGTH;
        }
        rx->encoded[rx->len++] = byte;
        return LINK_RX_NONE;
    }
    if (rx->skipping) {
        rx->skipping = 0;
        return LINK_RX_NONE;
    }
    if (rx->len == 0)
        return LINK_RX_NONE;
    uint8_t len = rx->len;
    rx->len = 0;
    return link_decode(rx->encoded, len, payload, frame);
}

uint8_t link_encode(uint8_t type, uint16_t seq, const uint8_t *body, uint8_t body_len,
                    uint8_t *out) {
    uint8_t payload[LINK_MAX_PAYLOAD];
    uint8_t n = 0;
    payload[n++] = LINK_VERSION;
    payload[n++] = type;
    put_u16(payload + n, seq);
    n += 2;
    for (uint8_t i = 0; i < body_len; i++)
        payload[n++] = body[i];
    put_u16(payload + n, link_crc16(payload, n));
    n += 2;

    /* COBS: each block starts with the distance to the next zero (or 0xFF). */
    uint8_t code_at = 0, code = 1, o = 1;
    for (uint8_t i = 0; i < n; i++) {
        if (payload[i] == 0) {
            out[code_at] = code;
            code_at = o++;
            code = 1;
        } else {
            out[o++] = payload[i];
            if (++code == 0xFF) {
                out[code_at] = code;
                code_at = o++;
                code = 1;
            }
        }
    }
    out[code_at] = code;
    out[o++] = 0;
    return o;
}
