/* The SOEM master's context of the C masters here (soem_context.h). */
#include <stdio.h>

#include "soem_context.h"

struct soem_bus bus;
ecx_contextt *const ctx = &bus.context;
ec_slavet *const slaves = bus.slavelist;

void context_init(void)
{
    ctx->port = &bus.port;
    ctx->slavelist = bus.slavelist;
    ctx->slavecount = &bus.slavecount;
    ctx->maxslave = EC_MAXSLAVE;
    ctx->grouplist = bus.grouplist;
    ctx->maxgroup = EC_MAXGROUP;
    ctx->esibuf = bus.esibuf;
    ctx->esimap = bus.esimap;
    ctx->elist = &bus.elist;
    ctx->idxstack = &bus.idxstack;
    ctx->ecaterror = &bus.ecaterror;
    ctx->DCtime = &bus.DCtime;
    ctx->SMcommtype = bus.SMcommtype;
    ctx->PDOassign = bus.PDOassign;
    ctx->PDOdesc = bus.PDOdesc;
    ctx->eepSM = &bus.eepSM;
    ctx->eepFMMU = &bus.eepFMMU;
}

void print_slave_state(int s)
{
    printf("slave %d: state %02Xh AL status %04Xh %s\n", s, slaves[s].state,
           slaves[s].ALstatuscode, ec_ALstatuscode2string(slaves[s].ALstatuscode));
}
