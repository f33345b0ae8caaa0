/*
 * FHPP on a Festo CMMO-ST over Modbus TCP with libmodbus, as a controller program does it (FHPP
 * manual Tab. 5.13; its extract kept beside the project, spec/cmmo-st-fhpp.md §2.5): every 2 ms
 * one FC 23 exchange writes the output telegram (CCON CPOS | byte 3 byte 4 | set-point,
 * registers 0…3, big-endian) and reads the input telegram (SCON SPOS | … | actual position).
 * Enable, home on the current position, move in direct mode to the target with the START / ACK
 * / MC handshake, then read the status with FC 03. Exit 0 when the axis is at the target, 1
 * when it is not, 2 on a Modbus error.
 *
 * Usage: fhpp_libmodbus HOST PORT [TARGET]   (TARGET in SINC, 0.01° by default)
 */
#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include <modbus.h>

enum {
    SCON_ENABLED = 0x01, SCON_OPEN = 0x02, SCON_FAULT = 0x08, SCON_OPM1 = 0x40,
    SPOS_ACK = 0x02, SPOS_MC = 0x04, SPOS_REF = 0x80,
    CCON_ENABLE = 0x01, CCON_STOP = 0x02, CCON_OPM1 = 0x40,
    CPOS_HALT = 0x01, CPOS_START = 0x02, CPOS_HOM = 0x04,
};

static modbus_t *ctx;
static uint8_t scon, spos;
static int32_t actual;

static void fail_modbus(const char *what)
{
    fprintf(stderr, "%s: %s\n", what, modbus_strerror(errno));
    exit(2);
}

/* One cycle: write the output telegram, read the input telegram, wait for the next 2 ms. */
static void cycle(uint8_t ccon, uint8_t cpos, uint8_t byte3, uint8_t byte4, int32_t setpoint)
{
    uint16_t out[4] = {
        (uint16_t)(ccon << 8 | cpos), (uint16_t)(byte3 << 8 | byte4),
        (uint16_t)((uint32_t)setpoint >> 16), (uint16_t)((uint32_t)setpoint & 0xFFFF),
    };
    uint16_t in[4];
    if (modbus_write_and_read_registers(ctx, 0, 4, out, 0, 4, in) != 4)
        fail_modbus("FC 23 exchange");
    scon = in[0] >> 8;
    spos = in[0] & 0xFF;
    actual = (int32_t)((uint32_t)in[2] << 16 | in[3]);
    struct timespec period = {0, 2000000};
    nanosleep(&period, NULL);
}

/* Cycles with the given telegram until `cond` holds; 3000 cycles (6 s) at most. */
#define UNTIL(what, cond, ccon, cpos, byte3, byte4, setpoint)                                \
    do {                                                                                     \
        int n_ = 0;                                                                          \
        for (;;) {                                                                           \
            cycle(ccon, cpos, byte3, byte4, setpoint);                                       \
            if (cond)                                                                        \
                break;                                                                       \
            if (++n_ == 3000) {                                                              \
                fprintf(stderr, "gave up waiting for %s: SCON %02Xh SPOS %02Xh\n", what,     \
                        scon, spos);                                                         \
                return 1;                                                                    \
            }                                                                                \
        }                                                                                    \
    } while (0)

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: %s HOST PORT [TARGET]\n", argv[0]);
        return 2;
    }
    int32_t target = argc > 3 ? (int32_t)strtol(argv[3], NULL, 0) : 27000;
    ctx = modbus_new_tcp(argv[1], atoi(argv[2]));
    if (ctx == NULL || modbus_connect(ctx) == -1)
        fail_modbus("connect");

    const uint8_t record = CCON_ENABLE | CCON_STOP, direct = record | CCON_OPM1;
    cycle(0, 0, 0, 0, 0);
    printf("power-on: SCON %02Xh SPOS %02Xh\n", scon, spos);
    UNTIL("enabled", (scon & (SCON_ENABLED | SCON_OPEN)) == (SCON_ENABLED | SCON_OPEN),
          record, CPOS_HALT, 0, 0, 0);
    printf("enabled: SCON %02Xh\n", scon);
    UNTIL("referenced", (spos & SPOS_REF) && (spos & SPOS_MC), record, CPOS_HALT | CPOS_HOM, 0,
          0, 0);
    UNTIL("ACK falls after homing", !(spos & SPOS_ACK), record, CPOS_HALT, 0, 0, 0);
    printf("homed: actual %d\n", actual);
    UNTIL("direct mode", scon & SCON_OPM1, direct, CPOS_HALT, 0, 100, target);
    UNTIL("ACK", spos & SPOS_ACK, direct, CPOS_HALT | CPOS_START, 0, 100, target);
    UNTIL("MC", spos & SPOS_MC, direct, CPOS_HALT, 0, 100, target);

    uint16_t in[4];
    if (modbus_read_registers(ctx, 0, 4, in) != 4)
        fail_modbus("FC 03 read");
    actual = (int32_t)((uint32_t)in[2] << 16 | in[3]);
    printf("reached: actual %d, target %d, SCON %02Xh SPOS %02Xh\n", actual, target, in[0] >> 8,
           in[0] & 0xFF);
    modbus_close(ctx);
    modbus_free(ctx);
    if (in[0] >> 8 & SCON_FAULT)
        return 1;
    return abs(actual - target) <= 180 ? 0 : 1;
}
