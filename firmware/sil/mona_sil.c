/*
 * mona-sil: the Mona firmware on a simulated ATmega328P (libsimavr), in real time.
 *
 *   mona-sil [--robot-id N] [--battery-mv MV] [--stats S] FIRMWARE.elf
 *
 * The UART is bridged to a pseudo-terminal that a driver opens as a serial device.
 * stdout, one line each, flushed:
 *   pty: /dev/pts/N                            once, when the MCU starts
 *   motors t=<s> left=<duty> right=<duty>      on every change of the motor outputs
 *   stats t=<s> wall=<s> rtf=<x> busy=<x>      every S seconds if --stats S > 0 (real-
 *                                              time factor of the interval, share of it
 *                                              spent computing)
 *   exit t=<s> wall=<s> rtf=<x> busy=<x>       at the end, over the whole run
 * <duty> is the PWM compare value (0..255, duty = value / 255), negative when the
 * direction pin says reverse; t is simulated time since reset. The outputs are read
 * from the registers (OCR1A/OCR1B, TCCR1A's COM bits, PORTD) each time the MCU goes
 * to sleep, so a line shows a settled state, never half of an update.
 * stdin (optional), one command a line:  ir R0 R1 R2 R3 R4  (raw ADC readings, TELEMETRY
 * order)  |  battery MV.
 * Simulated time is held to the wall clock: while the MCU sleeps the program waits on
 * the pty and stdin until the wall clock reaches the simulated time. SIGINT/SIGTERM
 * end it cleanly (exit 0). docs/firmware.md explains it.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <avr_adc.h>
#include <avr_eeprom.h>
#include <avr_uart.h>
#include <sim_avr.h>
#include <sim_elf.h>
#include <sim_irq.h>

#define MCU_NAME "atmega328p"
#ifndef MCU_HZ /* the firmware's F_CPU (firmware/Makefile) */
#define MCU_HZ 8000000UL
#endif
#define VCC_MV 5000
/* ATmega328P data-space addresses of the registers the motors are read from. */
#define REG_TCCR1A 0x80
#define REG_OCR1AL 0x88
#define REG_OCR1BL 0x8A
#define REG_PORTD 0x2B
#define COM1A1 7
#define COM1B1 5
#define LEFT_DIR_BIT 6  /* PD6 */
#define RIGHT_DIR_BIT 5 /* PD5 */
#define BATTERY_CHANNEL 6
#define BATTERY_DIVIDER 2 /* the firmware's assumption, firmware/mona/sensors.h */
static const int ir_channels[5] = {1, 0, 2, 7, 3};
/* How far simulated time may run ahead of the wall clock before the program waits: one
 * wait per few ms of simulated time instead of one per 1 ms tick of the firmware. Input
 * still wakes the wait at once, so it adds no latency. */
#define SLACK_S 0.004
/* Instructions run between two looks at the pty while the MCU stays awake. */
#define AWAKE_SERVICE_EVERY 20000

static volatile sig_atomic_t stopping;
static avr_t *avr;
static int pty_fd = -1, pty_slave = -1;
static int stdin_open = 1;

static uint8_t in_buf[4096];
static size_t in_len, in_off;
static int uart_xoff;
static uint8_t out_buf[512];
static size_t out_len;
static unsigned long out_dropped;

static struct timespec wall_start;
static int last_left = 0, last_right = 0;
static double stats_period = 0.0, next_stats = 0.0;
static double waited_s, last_stats_wall, last_stats_sim, last_stats_waited;
static char stdin_line[256];
static size_t stdin_len;
static avr_irq_t *adc_irq;

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)(ts.tv_sec - wall_start.tv_sec) + 1e-9 * (double)(ts.tv_nsec - wall_start.tv_nsec);
}

static double sim_s(avr_cycle_count_t cycle) { return (double)cycle / (double)avr->frequency; }

static void on_signal(int sig) {
    (void)sig;
    stopping = 1;
}

static void quiet_logger(avr_t *a, const int level, const char *format, va_list ap) {
    (void)a;
    if (level <= LOG_WARNING || getenv("MONA_SIL_TRACE"))
        vfprintf(stderr, format, ap);
}

static void flush_out(void) {
    size_t off = 0;
    if (!out_len)
        return;
    while (off < out_len) {
        ssize_t n = write(pty_fd, out_buf + off, out_len - off);
        if (n <= 0) { /* nobody reads and the pty is full: the bytes are lost, as on a wire */
            out_dropped += out_len - off;
            break;
        }
        off += (size_t)n;
    }
    out_len = 0;
}

static void on_uart_output(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    (void)param;
    if (out_len == sizeof out_buf)
        flush_out();
    out_buf[out_len++] = (uint8_t)value;
}

static void on_uart_xon(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq, (void)value, (void)param;
    uart_xoff = 0;
}

static void on_uart_xoff(struct avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq, (void)value, (void)param;
    uart_xoff = 1;
}

static void feed_uart(avr_irq_t *uart_in) {
    while (in_off < in_len && !uart_xoff)
        avr_raise_irq(uart_in, in_buf[in_off++]);
    if (in_off == in_len)
        in_off = in_len = 0;
}

static void set_adc(int channel, long millivolts) {
    if (millivolts < 0)
        millivolts = 0;
    if (millivolts > VCC_MV)
        millivolts = VCC_MV;
    avr_raise_irq(adc_irq + ADC_IRQ_ADC0 + channel, (uint32_t)millivolts);
}

static void set_ir_raw(int sensor, long raw) {
    set_adc(ir_channels[sensor], (raw * VCC_MV + 1022) / 1023);
}

static void stdin_command(char *line) {
    long v[5];
    if (sscanf(line, "ir %ld %ld %ld %ld %ld", &v[0], &v[1], &v[2], &v[3], &v[4]) == 5) {
        for (int i = 0; i < 5; i++)
            set_ir_raw(i, v[i]);
    } else if (sscanf(line, "battery %ld", &v[0]) == 1) {
        set_adc(BATTERY_CHANNEL, v[0] / BATTERY_DIVIDER);
    } else if (line[0]) {
        fprintf(stderr, "mona-sil: unknown command on stdin: %s (ir R0..R4 | battery MV)\n", line);
    }
}

static void read_stdin(void) {
    ssize_t n = read(STDIN_FILENO, stdin_line + stdin_len, sizeof stdin_line - 1 - stdin_len);
    if (n <= 0) {
        if (n == 0 || (errno != EAGAIN && errno != EINTR))
            stdin_open = 0;
        return;
    }
    stdin_len += (size_t)n;
    char *start = stdin_line, *nl;
    while ((nl = memchr(start, '\n', stdin_len - (size_t)(start - stdin_line)))) {
        *nl = 0;
        stdin_command(start);
        start = nl + 1;
    }
    stdin_len -= (size_t)(start - stdin_line);
    memmove(stdin_line, start, stdin_len);
    if (stdin_len == sizeof stdin_line - 1)
        stdin_len = 0; /* a line too long for any command */
}

static void read_pty(void) {
    if (in_len == sizeof in_buf)
        return;
    ssize_t n = read(pty_fd, in_buf + in_len, sizeof in_buf - in_len);
    if (n > 0)
        in_len += (size_t)n;
}

static void report_motors(void) {
    uint8_t tccr1a = avr->data[REG_TCCR1A], portd = avr->data[REG_PORTD];
    int left = (tccr1a & (1 << COM1A1)) ? avr->data[REG_OCR1AL] : 0;
    int right = (tccr1a & (1 << COM1B1)) ? avr->data[REG_OCR1BL] : 0;
    if (portd & (1 << LEFT_DIR_BIT))
        left = -left;
    if (portd & (1 << RIGHT_DIR_BIT))
        right = -right;
    if (left != last_left || right != last_right) {
        last_left = left;
        last_right = right;
        printf("motors t=%.6f left=%d right=%d\n", sim_s(avr->cycle), left, right);
        fflush(stdout);
    }
}

static void report_stats(double wall) {
    if (stats_period <= 0 || wall < next_stats)
        return;
    double sim = sim_s(avr->cycle), dwall = wall - last_stats_wall;
    printf("stats t=%.3f wall=%.3f rtf=%.4f busy=%.4f\n", sim, wall,
           (sim - last_stats_sim) / dwall, 1.0 - (waited_s - last_stats_waited) / dwall);
    fflush(stdout);
    last_stats_wall = wall;
    last_stats_sim = sim;
    last_stats_waited = waited_s;
    next_stats = wall + stats_period;
}

/* Exchange bytes and report outputs; then, if `until_cycle` is ahead of the wall clock,
 * wait for it (returning early when input arrives). */
static void service(avr_cycle_count_t until_cycle) {
    static avr_irq_t *uart_in;
    if (!uart_in)
        uart_in = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    report_motors();
    flush_out();
    feed_uart(uart_in);
    double wall = now_s();
    report_stats(wall);
    double target = sim_s(until_cycle);
    if (target - wall < SLACK_S)
        return;
    struct pollfd fds[2] = {{pty_fd, POLLIN, 0}, {STDIN_FILENO, POLLIN, 0}};
    nfds_t nfds = stdin_open ? 2 : 1;
    double timeout = target - wall;
    struct timespec ts = {(time_t)timeout, (long)((timeout - (double)(time_t)timeout) * 1e9)};
    int ready = ppoll(fds, nfds, &ts, NULL);
    waited_s += now_s() - wall;
    if (ready > 0) {
        if (fds[0].revents & POLLIN)
            read_pty();
        if (nfds > 1 && (fds[1].revents & (POLLIN | POLLHUP)))
            read_stdin();
    }
    feed_uart(uart_in);
}

static void on_sleep(avr_t *a, avr_cycle_count_t how_long) {
    service(a->cycle + how_long);
}

static int open_pty(void) {
    pty_fd = posix_openpt(O_RDWR | O_NOCTTY);
    if (pty_fd < 0 || grantpt(pty_fd) < 0 || unlockpt(pty_fd) < 0)
        return -1;
    const char *name = ptsname(pty_fd);
    /* Holding the slave open keeps the master readable while no driver has it open,
     * and sets the line raw: COBS frames carry every byte value. */
    pty_slave = open(name, O_RDWR | O_NOCTTY);
    if (pty_slave < 0)
        return -1;
    struct termios tio;
    tcgetattr(pty_slave, &tio);
    cfmakeraw(&tio);
    tcsetattr(pty_slave, TCSANOW, &tio);
    fcntl(pty_fd, F_SETFL, fcntl(pty_fd, F_GETFL) | O_NONBLOCK);
    printf("pty: %s\n", name);
    fflush(stdout);
    return 0;
}

static void usage_error(const char *message) {
    fprintf(stderr, "mona-sil: %s\nusage: mona-sil [--robot-id 0..254] [--battery-mv 0..10000] "
                    "[--stats SECONDS >= 0] FIRMWARE.elf\n", message);
    exit(2);
}

static long parse_long(const char *text, const char *field, long lo, long hi) {
    char *end;
    errno = 0;
    long v = strtol(text, &end, 10);
    if (errno || *end || end == text || v < lo || v > hi) {
        char message[160];
        snprintf(message, sizeof message, "%s: '%s' is not an integer in %ld..%ld", field, text,
                 lo, hi);
        usage_error(message);
    }
    return v;
}

/* ELF magic and e_machine EM_AVR (83): libsimavr would load anything and crash. */
static int is_avr_elf(const char *path) {
    unsigned char head[20];
    FILE *f = fopen(path, "rb");
    if (!f)
        return 0;
    size_t n = fread(head, 1, sizeof head, f);
    fclose(f);
    return n == sizeof head && memcmp(head, "\177ELF", 4) == 0 && head[18] == 83 && head[19] == 0;
}

int main(int argc, char **argv) {
    long robot_id = 0, battery_mv = 3900;
    static const struct option options[] = {
        {"robot-id", required_argument, 0, 'r'},
        {"battery-mv", required_argument, 0, 'b'},
        {"stats", required_argument, 0, 's'},
        {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0},
    };
    int opt;
    while ((opt = getopt_long(argc, argv, "h", options, NULL)) != -1) {
        char *end;
        switch (opt) {
        case 'r':
            robot_id = parse_long(optarg, "--robot-id", 0, 254);
            break;
        case 'b':
            battery_mv = parse_long(optarg, "--battery-mv", 0, BATTERY_DIVIDER * VCC_MV);
            break;
        case 's':
            stats_period = strtod(optarg, &end);
            if (*end || end == optarg || !(stats_period >= 0 && stats_period < 1e6))
                usage_error("--stats: seconds between stats lines, >= 0 (0: none)");
            break;
        case 'h':
            printf("usage: mona-sil [--robot-id 0..254] [--battery-mv 0..10000] "
                   "[--stats SECONDS] FIRMWARE.elf\n");
            return 0;
        default:
            usage_error("unknown option");
        }
    }
    if (optind != argc - 1)
        usage_error("FIRMWARE.elf: give exactly one firmware file");
    const char *path = argv[optind];
    if (access(path, R_OK) != 0) {
        fprintf(stderr, "mona-sil: FIRMWARE.elf: cannot read %s: %s\n", path, strerror(errno));
        return 2;
    }

    if (!is_avr_elf(path)) {
        fprintf(stderr, "mona-sil: FIRMWARE.elf: %s is no AVR ELF file (make -C firmware "
                        "builds firmware/build/mona.elf)\n", path);
        return 2;
    }
    avr_global_logger_set(quiet_logger);
    elf_firmware_t firmware;
    memset(&firmware, 0, sizeof firmware);
    if (elf_read_firmware(path, &firmware) != 0) {
        fprintf(stderr, "mona-sil: FIRMWARE.elf: %s is no AVR ELF file\n", path);
        return 2;
    }
    avr = avr_make_mcu_by_name(firmware.mmcu[0] ? firmware.mmcu : MCU_NAME);
    if (!avr) {
        fprintf(stderr, "mona-sil: no simulated MCU %s\n", firmware.mmcu);
        return 2;
    }
    avr_init(avr);
    avr_load_firmware(avr, &firmware);
    /* An ELF without simavr's .mmcu section leaves simavr's 1 MHz default. */
    avr->frequency = firmware.frequency ? firmware.frequency : MCU_HZ;
    avr->vcc = avr->avcc = avr->aref = VCC_MV;
    avr->log = getenv("MONA_SIL_TRACE") ? LOG_TRACE : LOG_WARNING;
    avr->sleep = on_sleep;

    uint8_t id = (uint8_t)robot_id;
    avr_eeprom_desc_t ee = {.ee = &id, .offset = 0, .size = 1};
    avr_ioctl(avr, AVR_IOCTL_EEPROM_SET, &ee);

    /* Keep the firmware's own stdio off the UART: the pty is its only line. */
    uint32_t uart_flags = 0;
    avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &uart_flags);
    uart_flags &= ~(uint32_t)AVR_UART_FLAG_STDIO;
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &uart_flags);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                            on_uart_output, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON),
                            on_uart_xon, NULL);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF),
                            on_uart_xoff, NULL);

    adc_irq = avr_io_getirq(avr, AVR_IOCTL_ADC_GETIRQ, 0);
    for (int i = 0; i < 5; i++)
        set_ir_raw(i, 1023); /* the original Mona reads 1023 when nothing is seen */
    set_adc(BATTERY_CHANNEL, battery_mv / BATTERY_DIVIDER);

    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);
    fcntl(STDIN_FILENO, F_SETFL, fcntl(STDIN_FILENO, F_GETFL) | O_NONBLOCK);

    if (open_pty() != 0) {
        fprintf(stderr, "mona-sil: cannot open a pseudo-terminal: %s\n", strerror(errno));
        return 1;
    }
    clock_gettime(CLOCK_MONOTONIC, &wall_start);
    next_stats = stats_period;

    int state = cpu_Running;
    unsigned long awake = 0;
    while (!stopping && state != cpu_Done && state != cpu_Crashed) {
        state = avr_run(avr);
        if (++awake >= AWAKE_SERVICE_EVERY) {
            awake = 0;
            service(avr->cycle);
        }
    }
    flush_out();
    if (state == cpu_Crashed)
        fprintf(stderr, "mona-sil: the simulated MCU crashed at t=%.6f s\n", sim_s(avr->cycle));
    double wall = now_s();
    printf("exit t=%.3f wall=%.3f rtf=%.4f busy=%.4f\n", sim_s(avr->cycle), wall,
           sim_s(avr->cycle) / wall, 1.0 - waited_s / wall);
    fflush(stdout);
    close(pty_slave);
    close(pty_fd);
    return state == cpu_Crashed ? 1 : 0;
}
