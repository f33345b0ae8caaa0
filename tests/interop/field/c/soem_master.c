/*
 * An EtherCAT master built on SOEM, doing what SOEM's own samples do (test/simple_ng,
 * test/linux/slaveinfo, test/linux/simple_test): find the slaves and print their identity, read the SII words of
 * the identity (ETG.1000.6 Tab. 16: vendor 0008h, product 000Ah, revision 000Ch) and compare
 * them with CoE 1018h, map the process data, go to Safe-Op and Op, then run cyclic process
 * data, checking the working counter of every cycle, while the CiA 402 controlword in the
 * outputs enables the drive (06h, 07h, 0Fh, each once the statusword shows the state before).
 * Back to Init at the end. Exit 0 when every step did what it set out to do.
 *
 * The ecx_ functions on a context of the master's own (soem_context.h, EC_VER2).
 *
 * Usage: soem_master IFNAME [CYCLES]   (1 ms cycles, 2000 by default)
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "soem_context.h"

/* Sleeps until `next` (CLOCK_MONOTONIC) and moves it one period on; a master that fell behind
 * starts again from now instead of sending the missed cycles in a burst. */
static void wait_period(struct timespec *next, long period_ns)
{
    next->tv_nsec += period_ns;
    while (next->tv_nsec >= 1000000000L) {
        next->tv_nsec -= 1000000000L;
        next->tv_sec++;
    }
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    if (now.tv_sec > next->tv_sec || (now.tv_sec == next->tv_sec && now.tv_nsec > next->tv_nsec))
        *next = now;
    else
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, next, NULL);
}

static int identity_matches(uint16 slave)
{
    static const struct { uint16 word; uint8 sub; const char *name; } rows[] = {
        {0x0008, 1, "vendor"}, {0x000A, 2, "product"}, {0x000C, 3, "revision"},
    };
    int ok = 1;
    for (size_t i = 0; i < sizeof rows / sizeof rows[0]; i++) {
        uint32 sii = ecx_readeeprom(ctx, slave, rows[i].word, EC_TIMEOUTEEP);
        uint32 coe = 0;
        int size = sizeof coe;
        int wkc = ecx_SDOread(ctx, slave, 0x1018, rows[i].sub, FALSE, &size, &coe, EC_TIMEOUTRXM);
        printf(" SII %04Xh %s %08X, CoE 1018h:%02X %08X\n", rows[i].word, rows[i].name,
               (unsigned)sii, rows[i].sub, (unsigned)coe);
        if (wkc <= 0 || sii != coe)
            ok = 0;
    }
    return ok;
}

int main(int argc, char *argv[])
{
    if (argc < 2) {
        fprintf(stderr, "usage: %s IFNAME [CYCLES]\n", argv[0]);
        return 2;
    }
    int cycles = argc > 2 ? atoi(argv[2]) : 2000;
    context_init();
    if (!ecx_init(ctx, argv[1])) {
        printf("no socket on %s (run as root)\n", argv[1]);
        return 1;
    }
    int result = 1;
    if (ecx_config_init(ctx, FALSE) <= 0) {
        printf("no slaves found\n");
        goto close;
    }
    printf("%d slaves found\n", bus.slavecount);
    for (int s = 1; s <= bus.slavecount; s++)
        printf("slave %d: %s man %08X id %08X rev %08X\n", s, slaves[s].name,
               (unsigned)slaves[s].eep_man, (unsigned)slaves[s].eep_id,
               (unsigned)slaves[s].eep_rev);
    for (int s = 1; s <= bus.slavecount; s++)
        if (!identity_matches((uint16)s)) {
            printf("slave %d: the SII and 1018h disagree\n", s);
            goto close;
        }

    ecx_config_map_group(ctx, bus.map, 0);
    ecx_configdc(ctx);
    ecx_statecheck(ctx, 0, EC_STATE_SAFE_OP, EC_TIMEOUTSTATE * 4);
    if (slaves[0].state != EC_STATE_SAFE_OP) {
        printf("not all slaves in Safe-Op: state %02Xh\n", slaves[0].state);
        goto close;
    }
    int expected_wkc = bus.grouplist[0].outputsWKC * 2 + bus.grouplist[0].inputsWKC;
    printf("Safe-Op; outputs %d bytes, inputs %d bytes, expected working counter %d\n",
           slaves[1].Obytes, slaves[1].Ibytes, expected_wkc);
    if (slaves[1].Obytes < 2 || slaves[1].Ibytes < 2) {
        printf("no controlword / statusword in the process data\n");
        goto close;
    }

    /* As simple_test: one valid frame first, then request Op and keep cycling until it is. */
    slaves[0].state = EC_STATE_OPERATIONAL;
    ecx_send_processdata(ctx);
    ecx_receive_processdata(ctx, EC_TIMEOUTRET);
    ecx_writestate(ctx, 0);
    int chk = 200;
    do {
        ecx_send_processdata(ctx);
        ecx_receive_processdata(ctx, EC_TIMEOUTRET);
        ecx_statecheck(ctx, 0, EC_STATE_OPERATIONAL, 50000);
    } while (chk-- && slaves[0].state != EC_STATE_OPERATIONAL);
    if (slaves[0].state != EC_STATE_OPERATIONAL) {
        ecx_readstate(ctx);
        for (int s = 1; s <= bus.slavecount; s++)
            print_slave_state(s);
        goto init;
    }
    printf("Op\n");

    static const uint16 sequence[] = {0x0006, 0x0007, 0x000F};
    static const uint16 expect[] = {0x0021, 0x0023, 0x0027};
    int step = 0, bad_wkc = 0, enabled_at = -1;
    uint16 sw = 0;
    struct timespec next;
    clock_gettime(CLOCK_MONOTONIC, &next);
    for (int i = 1; i <= cycles; i++) {
        uint16 cw = sequence[step];
        slaves[1].outputs[0] = (uint8)(cw & 0xFF);
        slaves[1].outputs[1] = (uint8)(cw >> 8);
        ecx_send_processdata(ctx);
        /* 100 ms: a shared machine may hold either side off the CPU; a frame that never comes
         * back still counts as a wrong working counter. */
        int wkc = ecx_receive_processdata(ctx, 100000);
        if (wkc < expected_wkc)
            bad_wkc++;
        sw = (uint16)(slaves[1].inputs[0] | slaves[1].inputs[1] << 8);
        if ((sw & 0x6F) == expect[step] && step < 2)
            step++;
        else if ((sw & 0x6F) == 0x27 && enabled_at < 0)
            enabled_at = i;
        wait_period(&next, 1000000L);
    }
    printf("%d cycles, %d with a wrong working counter, enabled at cycle %d, statusword %04Xh\n",
           cycles, bad_wkc, enabled_at, sw);
    result = bad_wkc == 0 && enabled_at > 0 && (sw & 0x6F) == 0x27 ? 0 : 1;

init:
    slaves[0].state = EC_STATE_INIT;
    ecx_writestate(ctx, 0);
    if (ecx_statecheck(ctx, 0, EC_STATE_INIT, EC_TIMEOUTSTATE) != EC_STATE_INIT) {
        printf("not back in Init\n");
        result = 1;
    }
close:
    ecx_close(ctx);
    printf("End, %s\n", result == 0 ? "ok" : "failed");
    return result;
}
