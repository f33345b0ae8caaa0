/*
 * The SOEM master's context of the C masters here (soem_master.c, soem_chain.c): the ecx_
 * functions run on a context of the master's own, as SOEM's test/simple_ng sets one up, since
 * the SOEM that pysoem carries is built with EC_VER2 (its context has fields the EC_VER1
 * default context of ethercatmain.c does not fill). Built with each master from soem_context.c.
 */
#ifndef SOEM_CONTEXT_H
#define SOEM_CONTEXT_H

#include "ethercat.h"

/* The master's context and everything it points to (simple_ng's Fieldbus). */
struct soem_bus {
    ecx_contextt context;
    uint8 map[4096];
    ecx_portt port;
    ec_slavet slavelist[EC_MAXSLAVE];
    int slavecount;
    ec_groupt grouplist[EC_MAXGROUP];
    uint8 esibuf[EC_MAXEEPBUF];
    uint32 esimap[EC_MAXEEPBITMAP];
    ec_eringt elist;
    ec_idxstackT idxstack;
    boolean ecaterror;
    int64 DCtime;
    ec_SMcommtypet SMcommtype[EC_MAX_MAPT];
    ec_PDOassignt PDOassign[EC_MAX_MAPT];
    ec_PDOdesct PDOdesc[EC_MAX_MAPT];
    ec_eepromSMt eepSM;
    ec_eepromFMMUt eepFMMU;
};

extern struct soem_bus bus;
/* The context (`&bus.context`) and its slaves (slave 0 is the group's summary). */
extern ecx_contextt *const ctx;
extern ec_slavet *const slaves;

/* Points the context at the rest of `bus`; before ecx_init. */
void context_init(void);

/* One line for slave `s`: its AL state and AL status code, with SOEM's words for it. */
void print_slave_state(int s);

#endif
