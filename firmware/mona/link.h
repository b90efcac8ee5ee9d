/* Mona link v1 framing (docs/design.md#mona-link): COBS, CRC-16/CCITT-FALSE, payload checks. */
#ifndef MONA_LINK_H
#define MONA_LINK_H

#include <stdint.h>

#define LINK_VERSION 1
#define LINK_MAX_PAYLOAD 64
#define LINK_HEADER 4 /* version u8, type u8, seq u16 */
#define LINK_MIN_PAYLOAD (LINK_HEADER + 2)
/* Longest COBS encoding of a payload, delimiter not included. */
#define LINK_MAX_ENCODED (LINK_MAX_PAYLOAD + 1 + LINK_MAX_PAYLOAD / 254)

enum link_type {
    MSG_WHEELS = 0x01,
    MSG_STOP = 0x02,
    MSG_PING = 0x03,
    MSG_HELLO = 0x81,
    MSG_TELEMETRY = 0x82,
    MSG_PONG = 0x83,
};

enum link_error {
    LINK_OK = 0,
    LINK_ERR_COBS,
    LINK_ERR_LENGTH,
    LINK_ERR_VERSION,
    LINK_ERR_CRC,
};

struct link_frame {
    uint8_t type;
    uint16_t seq;
    const uint8_t *body;
    uint8_t body_len;
};

uint16_t link_crc16(const uint8_t *data, uint8_t len);

/* Decode the COBS bytes of one frame (no delimiter) into `payload`; LINK_OK or why not. */
enum link_error link_decode(const uint8_t *encoded, uint8_t len, uint8_t *payload,
                            struct link_frame *frame);

/* A byte stream cut into frames at each 0x00 (zero-initialise it before the first byte). */
struct link_rx {
    uint8_t encoded[LINK_MAX_ENCODED];
    uint8_t len;
    uint8_t skipping; /* an oversize frame: dropped up to the next delimiter */
};

/* No frame ended with this byte (or an empty one, a sender flushing the line). */
#define LINK_RX_NONE (-1)

/* Take one received byte. LINK_OK: a frame ended and passed (decoded into `payload`,
 * described by `frame`); a link_error: a frame ended and was dropped, or (LINK_ERR_LENGTH)
 * grew past LINK_MAX_ENCODED and is dropped up to the next delimiter; LINK_RX_NONE. */
int link_receive(struct link_rx *rx, uint8_t byte, uint8_t *payload, struct link_frame *frame);

/* Encode a frame with its trailing 0x00 into `out` (LINK_MAX_ENCODED + 1 bytes);
 * returns its length. `body_len` must be <= LINK_MAX_PAYLOAD - LINK_MIN_PAYLOAD. */
uint8_t link_encode(uint8_t type, uint16_t seq, const uint8_t *body, uint8_t body_len,
                    uint8_t *out);

static inline void put_u16(uint8_t *p, uint16_t v) {
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static inline uint16_t get_u16(const uint8_t *p) { return (uint16_t)(p[0] | (p[1] << 8)); }

#endif
