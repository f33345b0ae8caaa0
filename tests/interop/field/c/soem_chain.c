/*
 * An EtherCAT master on SOEM for a chain of CiA 402 drives, as a PLC's cyclic task runs one:
 * scan the line and count the slaves, assign each drive's cyclic synchronous position PDOs
 * over CoE in Pre-Op (1C12h / 1C13h, ETG.6010: controlword + target position out, statusword +
 * position actual value in) and set 6060h = 8 (CSP), map the process data, switch on
 * distributed clocks with a SYNC0 of the cycle on every slave (or run free), Safe-Op, Op,
 * then a fixed number of cycles sleeping until the next period between them (a
 * normal-priority task's clock_nanosleep), the working counter checked on every cycle. The
 * drives are enabled (06h, 07h, 0Fh, each once every statusword shows the state before) and
 * then each follows a ramp of its own (drive k moves k + 1 increments a cycle).
 *
 * Printed at the end: cycles, wrong working counters, late cycles (the next period had begun
 * when the cycle's frame came back), the frame's round trip (p50 / p99 / max), how many drives
 * were enabled, the largest following lag, and whether every slave is still in Op; then the
 * first cycle whose inputs showed a drive in Fault and, before it, the longest wake-up delay
 * and the longest round trip with their cycles, so a run that lost its slaves tells whether
 * the master was held off its CPU (a wake-up delay) or the frame was (a round trip). Exit 0 when
 * every cycle's working counter was right, every drive enabled, followed and stayed in Op.
 *
 * Usage: soem_chain IFNAME SLAVES CYCLES PERIOD_NS DC RXPDOS TXPDOS
 *   DC: 1 = SYNC0 every PERIOD_NS, 0 = free run; RXPDOS / TXPDOS: hex lists such as 1602 or
 *   1600,1602 (they must map 6040h + 607Ah and 6041h + 6064h, 6 bytes each way).
 *
 * The ecx_ functions on a context of the master's own (soem_context.h, EC_VER2).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "soem_context.h"

static int64_t now_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (int64_t)t.tv_sec * 1000000000LL + t.tv_nsec;
}

static void sleep_until(int64_t at)
{
    struct timespec t = {.tv_sec = at / 1000000000LL, .tv_nsec = at % 1000000000LL};
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, NULL);
}

/* "1600,1602" into `out` (at most 4); the count. */
static int parse_pdos(const char *text, uint16 *out)
{
    int n = 0;
    char *end;
    while (*text && n < 4) {
        out[n++] = (uint16)strtoul(text, &end, 16);
        if (*end != ',')
            break;
        text = end + 1;
    }
    return n;
}

static int sdo_u8(uint16 s, uint16 index, uint8 sub, uint8 v)
{
    return ecx_SDOwrite(ctx, s, index, sub, FALSE, sizeof v, &v, EC_TIMEOUTRXM) > 0;
}

static int sdo_u16(uint16 s, uint16 index, uint8 sub, uint16 v)
{
    return ecx_SDOwrite(ctx, s, index, sub, FALSE, sizeof v, &v, EC_TIMEOUTRXM) > 0;
}

/* 1C12h / 1C13h as CiA 301 / ETG.1000.6 change an assignment: count 0, the entries, count. */
static int assign(uint16 s, uint16 index, const uint16 *pdos, int n)
{
    if (!sdo_u8(s, index, 0, 0))
        return 0;
    for (int k = 0; k < n; k++)
        if (!sdo_u16(s, index, (uint8)(k + 1), pdos[k]))
            return 0;
    return sdo_u8(s, index, 0, (uint8)n);
}

static int cmp_i64(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

static uint16 get_u16(const uint8 *p) { return (uint16)(p[0] | p[1] << 8); }
static int32 get_i32(const uint8 *p) { return (int32)((uint32)p[0] | (uint32)p[1] << 8 | (uint32)p[2] << 16 | (uint32)p[3] << 24); }
static void put_u16(uint8 *p, uint16 v) { p[0] = (uint8)v; p[1] = (uint8)(v >> 8); }
static void put_i32(uint8 *p, int32 v) { for (int i = 0; i < 4; i++) p[i] = (uint8)((uint32)v >> (8 * i)); }

int main(int argc, char *argv[])
{
    if (argc < 8) {
        fprintf(stderr, "usage: %s IFNAME SLAVES CYCLES PERIOD_NS DC RXPDOS TXPDOS\n", argv[0]);
        return 2;
    }
    int want = atoi(argv[2]);
    int cycles = atoi(argv[3]);
    int64_t period = atoll(argv[4]);
    int dc = atoi(argv[5]);
    uint16 rx[4], tx[4];
    int nrx = parse_pdos(argv[6], rx), ntx = parse_pdos(argv[7], tx);
    context_init();
    if (!ecx_init(ctx, argv[1])) {
        printf("no socket on %s (run as root)\n", argv[1]);
        return 1;
    }
    int result = 1;
    int found = ecx_config_init(ctx, FALSE);
    printf("%d slaves found\n", found);
    if (found != want)
        goto close;
    printf("slave 1: man %08X id %08X rev %08X; slave %d: man %08X id %08X rev %08X\n",
           (unsigned)slaves[1].eep_man, (unsigned)slaves[1].eep_id, (unsigned)slaves[1].eep_rev,
           found, (unsigned)slaves[found].eep_man, (unsigned)slaves[found].eep_id,
           (unsigned)slaves[found].eep_rev);
    for (int s = 1; s <= found; s++) {
        if (!assign((uint16)s, 0x1C12, rx, nrx) || !assign((uint16)s, 0x1C13, tx, ntx) ||
            !sdo_u8((uint16)s, 0x6060, 0, 8)) {
            printf("slave %d: the CSP PDOs or 6060h not taken\n", s);
            goto close;
        }
    }
    ecx_config_map_group(ctx, bus.map, 0);
    if (dc) {
        if (!ecx_configdc(ctx)) {
            printf("no distributed clocks\n");
            goto close;
        }
        for (int s = 1; s <= found; s++)
            ecx_dcsync0(ctx, (uint16)s, TRUE, (uint32)period, 0);
    }
    ecx_statecheck(ctx, 0, EC_STATE_SAFE_OP, EC_TIMEOUTSTATE * 4);
    if (slaves[0].state != EC_STATE_SAFE_OP) {
        ecx_readstate(ctx);
        for (int s = 1; s <= found; s++)
            if (slaves[s].state != EC_STATE_SAFE_OP)
                print_slave_state(s);
        printf("not all slaves in Safe-Op\n");
        goto close;
    }
    int expected_wkc = bus.grouplist[0].outputsWKC * 2 + bus.grouplist[0].inputsWKC;
    for (int s = 1; s <= found; s++)
        if (slaves[s].Obytes != 6 || slaves[s].Ibytes != 6) {
            printf("slave %d: %d bytes out, %d in; 6 each expected\n", s, slaves[s].Obytes,
                   slaves[s].Ibytes);
            goto close;
        }
    printf("Safe-Op; %d bytes out, %d in, expected working counter %d, %s, period %lld ns\n",
           (int)bus.grouplist[0].Obytes, (int)bus.grouplist[0].Ibytes, expected_wkc,
           dc ? "DC" : "free run", (long long)period);

    int64_t *rtt = calloc((size_t)cycles, sizeof *rtt);
    int32 *target = calloc((size_t)found + 1, sizeof *target);
    if (!rtt || !target)
        goto close;

    /* As simple_test: valid outputs first, then Op requested, cycling on the period until
     * every slave is there (reading 64 AL states takes longer than a cycle: read after). */
    int64_t next = now_ns();
    slaves[0].state = EC_STATE_OPERATIONAL;
    ecx_send_processdata(ctx);
    ecx_receive_processdata(ctx, EC_TIMEOUTRET);
    ecx_writestate(ctx, 0);
    int op = 0;
    for (int i = 0; i < 2000 && !op; i++) {
        next += period;
        sleep_until(next);
        ecx_send_processdata(ctx);
        ecx_receive_processdata(ctx, 100000);
        if (i % 50 == 49)
            op = ecx_readstate(ctx) == EC_STATE_OPERATIONAL;
    }
    if (!op) {
        for (int s = 1; s <= found; s++)
            if (slaves[s].state != EC_STATE_OPERATIONAL)
                print_slave_state(s);
        printf("not all slaves in Op\n");
        goto init;
    }
    printf("Op\n");
    for (int s = 1; s <= found; s++)
        target[s] = get_i32(slaves[s].inputs + 2);

    static const uint16 sequence[] = {0x0006, 0x0007, 0x000F};
    static const uint16 expect[] = {0x0021, 0x0023, 0x0027};
    int step = 0, bad_wkc = 0, late = 0, enabled_at = -1;
    /* Where a run went wrong: the first cycle whose inputs show a drive in Fault (a drive that
     * lost its SYNC0 grid reports it in its statusword, CMMP-AS §2.11), and before it the
     * master's longest wake-up delay (past its period, or past the previous frame's return when
     * that came later) and the longest round trip, each with its cycle. */
    int64_t worst_wake = 0, worst_rtt = 0, back = 0;
    int worst_wake_at = -1, worst_rtt_at = -1, fault_at = -1, fault_slave = 0;
    next = now_ns();
    for (int i = 0; i < cycles; i++) {
        next += period;
        sleep_until(next);
        for (int s = 1; s <= found; s++) {
            if (enabled_at >= 0)
                target[s] += s;
            put_u16(slaves[s].outputs, sequence[step]);
            put_i32(slaves[s].outputs + 2, target[s]);
        }
        int64_t sent = now_ns();
        ecx_send_processdata(ctx);
        /* 100 ms: a frame that never comes back counts as a wrong working counter. */
        int wkc = ecx_receive_processdata(ctx, 100000);
        int64_t woke = sent - (back > next ? back : next);
        back = now_ns();
        rtt[i] = back - sent;
        if (fault_at < 0 && woke > worst_wake) {
            worst_wake = woke;
            worst_wake_at = i;
        }
        if (fault_at < 0 && rtt[i] > worst_rtt) {
            worst_rtt = rtt[i];
            worst_rtt_at = i;
        }
        if (wkc != expected_wkc)
            bad_wkc++;
        for (int s = 1; s <= found && fault_at < 0; s++)
            if (get_u16(slaves[s].inputs) & 0x0008) {
                fault_at = i;
                fault_slave = s;
            }
        if (back > next + period)
            late++;
        int all = 1;
        for (int s = 1; s <= found; s++)
            all &= (get_u16(slaves[s].inputs) & 0x6F) == expect[step];
        if (all && step < 2)
            step++;
        else if (all && step == 2 && enabled_at < 0)
            enabled_at = i;
    }
    /* 100 ms (at least 20 cycles) of the last set-points, then the lag of each drive: at
     * 4 kHz drive k moves k + 1 increments every 250 us, four times as fast as at 1 kHz, and
     * 20 ms left it still settling (lag 297-703 where it stands at 29 after 100 ms). */
    int32 worst_lag = 0;
    int enabled = 0;
    int hold = (int)(100000000LL / period);
    for (int i = 0; i < (hold > 20 ? hold : 20); i++) {
        next += period;
        sleep_until(next);
        ecx_send_processdata(ctx);
        if (ecx_receive_processdata(ctx, 100000) != expected_wkc)
            bad_wkc++;
    }
    for (int s = 1; s <= found; s++) {
        int32 lag = get_i32(slaves[s].inputs + 2) - target[s];
        if (lag < 0)
            lag = -lag;
        if (lag > worst_lag)
            worst_lag = lag;
        enabled += (get_u16(slaves[s].inputs) & 0x6F) == 0x27;
    }
    int still_op = ecx_readstate(ctx) == EC_STATE_OPERATIONAL;
    qsort(rtt, (size_t)cycles, sizeof *rtt, cmp_i64);
    printf("%d cycles, %d with a wrong working counter, %d late; round trip p50 %.1f us "
           "p99 %.1f us max %.1f us; %d of %d enabled (at cycle %d), largest lag %d, %s\n",
           cycles, bad_wkc, late, rtt[cycles / 2] / 1e3, rtt[cycles * 99 / 100] / 1e3,
           rtt[cycles - 1] / 1e3, enabled, found, enabled_at, (int)worst_lag,
           still_op ? "all in Op" : "not all in Op");
    printf("%s: longest wake-up delay %.1f us at cycle %d, longest round trip %.1f us at "
           "cycle %d; ", fault_at >= 0 ? "before the first fault" : "whole run",
           worst_wake / 1e3, worst_wake_at, worst_rtt / 1e3, worst_rtt_at);
    if (fault_at >= 0)
        printf("first fault in the inputs at cycle %d (slave %d)\n", fault_at, fault_slave);
    else
        printf("no drive faulted\n");
    if (!still_op)
        for (int s = 1; s <= found; s++)
            if (slaves[s].state != EC_STATE_OPERATIONAL)
                print_slave_state(s);
    result = bad_wkc == 0 && enabled == found && still_op && worst_lag < 200 ? 0 : 1;

init:
    slaves[0].state = EC_STATE_INIT;
    ecx_writestate(ctx, 0);
    ecx_statecheck(ctx, 0, EC_STATE_INIT, EC_TIMEOUTSTATE);
close:
    ecx_close(ctx);
    printf("End, %s\n", result == 0 ? "ok" : "failed");
    return result;
}
