/*
 * A Kinco FD3 on its RS485 port with libmodbus (Modbus RTU, 19200 8N1, station 1), as an AGV
 * controller drives it: the registers of the Kinco manual's extract kept beside the project
 * (spec/kinco-fd-cd.md §2.3: 3100h controlword, 3200h statusword, 3500h Operation_Mode, 4000h
 * Target_Position, 4A00h-4C00h profile, 3700h Pos_Actual, 3900h the position window; 32-bit
 * values low word first). Twenty times:
 * controlword 00h and wait for SWITCH ON DISABLED, then 06h, 07h, 0Fh each after its answer
 * and poll the statusword for OPERATION ENABLED (0.5 s at most); then a profile-position move
 * with 2Fh → 3Fh, polled until target reached at the target. The controlword and the mode must
 * be free of the factory inputs (Din1/Din3_Function = 0, as a commissioned drive has them).
 * Exit 0 when every run enabled and the axis reached the target, 1 when not, 2 on a Modbus
 * error.
 *
 * Usage: kinco_rtu_libmodbus DEVICE [TARGET]
 */
#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include <modbus.h>

#define RUNS 20

static modbus_t *ctx;

static void fail_modbus(const char *what, int reg)
{
    fprintf(stderr, "%s %04Xh: %s\n", what, reg, modbus_strerror(errno));
    exit(2);
}

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + (double)t.tv_nsec / 1e9;
}

static void write16(int reg, uint16_t value)
{
    if (modbus_write_register(ctx, reg, value) != 1)
        fail_modbus("FC 06 write", reg);
}

static void write32(int reg, int32_t value)
{
    uint16_t words[2] = {(uint16_t)((uint32_t)value & 0xFFFF), (uint16_t)((uint32_t)value >> 16)};
    if (modbus_write_registers(ctx, reg, 2, words) != 2)
        fail_modbus("FC 10 write", reg);
}

static uint16_t read16(int reg)
{
    uint16_t value;
    if (modbus_read_registers(ctx, reg, 1, &value) != 1)
        fail_modbus("FC 03 read", reg);
    return value;
}

static int32_t read32(int reg)
{
    uint16_t words[2];
    if (modbus_read_registers(ctx, reg, 2, words) != 2)
        fail_modbus("FC 03 read", reg);
    return (int32_t)((uint32_t)words[1] << 16 | words[0]);
}

/* Polls the statusword until (sw & mask) == value or `seconds` pass; the last statusword. */
static uint16_t statusword_until(uint16_t mask, uint16_t value, double seconds, int *ok)
{
    double deadline = now() + seconds;
    uint16_t sw;
    do {
        sw = read16(0x3200);
        if ((sw & mask) == value) {
            *ok = 1;
            return sw;
        }
    } while (now() < deadline);
    *ok = 0;
    return sw;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: %s DEVICE [TARGET]\n", argv[0]);
        return 2;
    }
    int32_t target = argc > 2 ? (int32_t)strtol(argv[2], NULL, 0) : 50000;
    ctx = modbus_new_rtu(argv[1], 19200, 'N', 8, 1);
    if (ctx == NULL || modbus_set_slave(ctx, 1) == -1 || modbus_connect(ctx) == -1)
        fail_modbus("open", 0);

    write16(0x3500, 1);         /* profile position */
    write32(0x4A00, 1638400);   /* 600 rpm */
    write32(0x4B00, 16384);     /* 100 rps/s */
    write32(0x4C00, 16384);

    int enabled = 0, ok;
    uint16_t sw;
    for (int run = 1; run <= RUNS; run++) {
        write16(0x3100, 0x00);
        sw = statusword_until(0x4F, 0x40, 1.0, &ok);
        if (!ok) {
            fprintf(stderr, "run %d: 00h left the statusword at %04Xh\n", run, sw);
            return 1;
        }
        write16(0x3100, 0x06);
        write16(0x3100, 0x07);
        write16(0x3100, 0x0F);
        sw = statusword_until(0x6F, 0x27, 0.5, &ok);
        if (ok)
            enabled++;
        else
            printf("run %d: statusword %04Xh 0.5 s after the last answer\n", run, sw);
    }
    printf("enabled in %d of %d runs\n", enabled, RUNS);
    if (enabled != RUNS)
        return 1;

    int32_t window = read32(0x3900), pos = 0;
    write32(0x4000, target);
    write16(0x3100, 0x2F);
    write16(0x3100, 0x3F);
    double deadline = now() + 5.0;
    do {
        sw = read16(0x3200);
        pos = read32(0x3700);
        if ((sw & 0x0400) && abs(pos - target) <= window) {
            printf("reached: Pos_Actual %d, target %d, statusword %04Xh\n", pos, target, sw);
            modbus_close(ctx);
            modbus_free(ctx);
            return 0;
        }
    } while (now() < deadline);
    fprintf(stderr, "not reached: Pos_Actual %d, target %d, statusword %04Xh\n", pos, target, sw);
    return 1;
}
