"""CiA 301 §7.3.5 over socketcand: no configurable COB-ID of any personality takes a
restricted CAN-ID (000h, 001h–07Fh, 101h–180h, 581h–5FFh, 601h–67Fh, 6E0h–6FFh, 701h–77Fh,
780h–7FFh): SYNC 1005h, EMCY 1014h where it is writable, every RPDO and TPDO. A refused
write is aborted with 0609 0030h and leaves the old value."""

import struct

import can
import pytest

from conftest import recv_id, sdo_request

RESTRICTED = [0x000, 0x001, 0x002, 0x07F, 0x101, 0x180, 0x581, 0x5FF, 0x601, 0x67F, 0x6E0,
              0x6FF, 0x701, 0x77F, 0x780, 0x7FF]
INVALID_VALUE = 0x06090030
VALUE_TOO_HIGH = 0x06090031
# (personality, node): the CANopen ones with their manual's example node.
DEVICES = [("cmmp-as", 1), ("nanotec-smci47s", 34), ("nanotec-pd4n", 5)]


def write_u32(bus, node, index, sub, value):
    """Expedited 4-byte download; returns the abort code, or None for success."""
    req = struct.pack("<BHBI", 0x23, index, sub, value)
    r = sdo_request(bus, node, req)
    if r[0] == 0x80:
        return struct.unpack_from("<I", r, 4)[0]
    assert r[0] == 0x60, r.hex(" ")
    return None


def read_u32(bus, node, index, sub):
    r = sdo_request(bus, node, struct.pack("<BHBI", 0x40, index, sub, 0))
    assert r[0] in (0x43, 0x4F, 0x4B), r.hex(" ")
    return struct.unpack_from("<I", r, 4)[0]


def pre_operational(bus, node):
    bus.send(can.Message(arbitration_id=0x000, data=[0x80, node], is_extended_id=False))
    recv_id(bus, 0x700 + node, timeout=0.3)


@pytest.mark.parametrize("device,node", DEVICES)
def test_sync_cob_id_refuses_restricted_ids(launch, raw_bus, device, node):
    bus = raw_bus(launch(device, node))
    pre_operational(bus, node)
    before = read_u32(bus, node, 0x1005, 0)
    for cob in RESTRICTED:
        assert write_u32(bus, node, 0x1005, 0, cob) == INVALID_VALUE, f"{device}: SYNC on {cob:03X}h"
    # No personality produces SYNC (the Nanotec's 1005h range already ends below bit 30).
    assert write_u32(bus, node, 0x1005, 0, 0x4000_0080) in (INVALID_VALUE, VALUE_TOO_HIGH)
    assert read_u32(bus, node, 0x1005, 0) == before
    assert write_u32(bus, node, 0x1005, 0, 0x0000_0081) is None, "an allowed ID"
    assert read_u32(bus, node, 0x1005, 0) == 0x81


def test_emcy_cob_id_rules_on_the_cmmp_as(launch, raw_bus):
    bus = raw_bus(launch("cmmp-as", 1))
    pre_operational(bus, 1)
    assert read_u32(bus, 1, 0x1014, 0) == 0x81
    assert write_u32(bus, 1, 0x1014, 0, 0x90) == INVALID_VALUE, "changed while valid"
    assert write_u32(bus, 1, 0x1014, 0, 0x8000_0081) is None, "switched off"
    for cob in RESTRICTED:
        assert write_u32(bus, 1, 0x1014, 0, cob) == INVALID_VALUE, f"EMCY on {cob:03X}h"
    assert write_u32(bus, 1, 0x1014, 0, 0x90) is None
    assert read_u32(bus, 1, 0x1014, 0) == 0x90


@pytest.mark.parametrize("device,node", DEVICES)
def test_pdo_cob_ids_refuse_restricted_ids(launch, raw_bus, device, node):
    bus = raw_bus(launch(device, node))
    pre_operational(bus, node)
    for comm in (0x1400, 0x1401, 0x1402, 0x1403, 0x1800, 0x1801, 0x1802, 0x1803):
        before = read_u32(bus, node, comm, 1)
        off = before | 0x8000_0000
        assert write_u32(bus, node, comm, 1, off) is None, f"{device} {comm:04X}h off"
        for cob in RESTRICTED:
            code = write_u32(bus, node, comm, 1, cob)
            assert code == INVALID_VALUE, f"{device} {comm:04X}h on {cob:03X}h: {code}"
        assert read_u32(bus, node, comm, 1) & 0x7FF == before & 0x7FF
