/*
 * The firmware's Mona link code (firmware/mona/link.c) on the host, for
 * tests/unit/test_firmware_link.py: records on stdin, one answer line each on stdout.
 *
 *   'd' len u8, len bytes            decode those COBS bytes (no delimiter):
 *                                    "ok TYPE SEQ BODYHEX" or "err CODE" (enum link_error)
 *   'e' type u8, seq u16 LE, n u8, n bytes
 *                                    encode that frame: "enc HEX" (delimiter included)
 *   's' n u16 LE, n bytes            a byte stream, as the firmware receives one
 *                                    (link_receive from a fresh state): a line as for
 *                                    'd' per frame that ends or is dropped, then "end"
 *
 * Built with AddressSanitizer and UBSan by the test, so a read or write out of bounds
 * on any input ends it with a report instead of an answer.
 */
#include <stdio.h>
#include <stdlib.h>

#include "link.h"

static int read_bytes(uint8_t *buf, int n) { return (int)fread(buf, 1, (size_t)n, stdin) == n; }

static void print_hex(const uint8_t *p, int n) {
    for (int i = 0; i < n; i++)
        printf("%02x", p[i]);
}

static void print_result(int e, const struct link_frame *frame) {
    if (e == LINK_OK) {
        printf("ok %u %u ", frame->type, frame->seq);
        print_hex(frame->body, frame->body_len);
        printf("\n");
    } else {
        printf("err %d\n", e);
    }
}

int main(void) {
    int kind;
    while ((kind = getchar()) != EOF) {
        uint8_t head[4], data[256];
        if (kind == 'd') {
            if (!read_bytes(head, 1) || !read_bytes(data, head[0]))
                return 2;
            /* exactly the bytes of the record, on the heap: a read past them is caught */
            uint8_t *encoded = malloc(head[0] ? head[0] : 1), payload[LINK_MAX_PAYLOAD];
            if (!encoded)
                return 2;
            for (int i = 0; i < head[0]; i++)
                encoded[i] = data[i];
            struct link_frame frame;
            print_result(link_decode(encoded, head[0], payload, &frame), &frame);
            free(encoded);
        } else if (kind == 'e') {
            if (!read_bytes(head, 4) || !read_bytes(data, head[3]))
                return 2;
            uint8_t out[LINK_MAX_ENCODED + 1];
            uint8_t n = link_encode(head[0], get_u16(head + 1), data, head[3], out);
            printf("enc ");
            print_hex(out, n);
            printf("\n");
        } else if (kind == 's') {
            if (!read_bytes(head, 2))
                return 2;
            struct link_rx rx = {{0}, 0, 0};
            uint8_t payload[LINK_MAX_PAYLOAD];
            struct link_frame frame;
            for (int n = get_u16(head); n > 0; n--) {
                int byte = getchar();
                if (byte == EOF)
                    return 2;
                int e = link_receive(&rx, (uint8_t)byte, payload, &frame);
                if (e != LINK_RX_NONE)
                    print_result(e, &frame);
            }
            printf("end\n");
        } else {
            return 2;
        }
    }
    return 0;
}
