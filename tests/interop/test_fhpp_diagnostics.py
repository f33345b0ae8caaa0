"""CMMO-ST diagnostics over Modbus TCP, driven by pymodbus: faults provoked with the cyclic
telegram alone show in SCON.FAULT and in FC 0x07 (Read Exception Status = the diagnostic number,
§8.2 g of the FHPP manual's extract kept beside the project, spec/cmmo-st-fhpp.md), and a
CCON.RESET rising edge acknowledges them (§8.2 e, T10: the reaction of 3Fh / 28h keeps the
output stage on).
"""

from __future__ import annotations

from test_fhpp_modbus import (  # noqa: F401  (cmmo is a fixture)
    CCON_RECORD_ENABLED, CPOS_HALT, CPOS_START, SCON_ENABLED, SCON_FAULT, SPOS_ACK, SPOS_MC,
    cmmo, cycle_until, decode, enable_and_home, exchange, telegram)

CCON_RESET = 0x08
RECORD_INVALID = 0x3F   # App. D 3Fh record invalid
HOMING_REQUIRED = 0x28  # App. D 28h homing required


def start_record(client, number, until, what):
    """Record selection: the number in byte 3, START rising and held until `until` holds for
    the input telegram (the drive samples the telegram once per millisecond cycle), then
    START away."""
    exchange(client, telegram(CCON_RECORD_ENABLED, CPOS_HALT, number))
    s = cycle_until(client, telegram(CCON_RECORD_ENABLED, CPOS_HALT | CPOS_START, number),
                    until, timeout=3, what=what)
    exchange(client, telegram(CCON_RECORD_ENABLED, CPOS_HALT, number))
    return s


def acknowledge(client):
    """RESET rising edge with ENABLE + STOP (T10), until SCON.FAULT falls."""
    exchange(client, telegram(CCON_RECORD_ENABLED, CPOS_HALT))
    s = cycle_until(client, telegram(CCON_RECORD_ENABLED | CCON_RESET, CPOS_HALT),
                    lambda s: not s["scon"] & SCON_FAULT, timeout=3, what="fault reset")
    exchange(client, telegram(CCON_RECORD_ENABLED, CPOS_HALT))
    return s


def test_invalid_record_number_is_fault_3fh_in_scon_and_fc_07_until_reset(cmmo):
    twin = cmmo()
    c = twin.client()
    try:
        enable_and_home(c)
        assert c.read_exception_status().status == 0
        start_record(c, 70, lambda s: s["scon"] & SCON_FAULT, "fault")  # records are 1…64
        s = cycle_until(c, telegram(CCON_RECORD_ENABLED, CPOS_HALT, 70),
                        lambda s: s["scon"] & SCON_FAULT and s["spos"] & SPOS_MC,
                        timeout=3, what="fault 3Fh")
        assert not s["spos"] & SPOS_ACK, s
        rr = c.read_exception_status()
        assert not rr.isError(), rr
        assert rr.status == RECORD_INVALID, hex(rr.status)  # FHPP-MB-05: the fault number
        # Reaction E: Quick-Stop ramp, the output stage stays on.
        assert s["scon"] & SCON_ENABLED, s
        s = acknowledge(c)
        assert s["scon"] & SCON_ENABLED, s
        assert c.read_exception_status().status == 0
        # A valid record runs afterwards (record 1: target 0, at once MC).
        start_record(c, 1, lambda s: s["spos"] & SPOS_ACK, "ACK of record 1")
        cycle_until(c, telegram(CCON_RECORD_ENABLED, CPOS_HALT, 1),
                    lambda s: s["spos"] & SPOS_MC and not s["scon"] & SCON_FAULT,
                    timeout=3, what="record 1 done")
    finally:
        c.close()


def test_start_before_homing_is_fault_28h_and_reset_clears_it(cmmo):
    twin = cmmo()
    c = twin.client()
    try:
        s = exchange(c, telegram(0, 0))
        assert (s["scon"], s["spos"]) == (0x10, 0x04), s
        cycle_until(c, telegram(CCON_RECORD_ENABLED, CPOS_HALT),
                    lambda s: (s["scon"], s["spos"]) == (0x13, 0x05), what="enabled")
        start_record(c, 1, lambda s: s["scon"] & SCON_FAULT, "fault 28h")
        assert c.read_exception_status().status == HOMING_REQUIRED
        # The raw FC 0x03 image says the same as FC 0x17.
        rr = c.read_holding_registers(0, count=4)
        assert decode(rr.registers)["scon"] & SCON_FAULT
        acknowledge(c)
        assert c.read_exception_status().status == 0
    finally:
        c.close()


def test_the_diagnostic_memory_is_read_through_the_parameter_channel(cmmo):
    """PNU 200…204 over the EFPC bytes 9…16 (FC 0x17 with 8 registers): the power-on entry,
    a fault coming (01h) and going (00h) with its number and time stamp, newest first, and
    PNU 204:3 = 1 clearing the memory and writing the start-up event 3Dh (FHPP-DIAG-04)."""
    from test_fhpp_parameter_channel import read, write

    twin = cmmo()
    c = twin.client()
    hold = telegram(CCON_RECORD_ENABLED, CPOS_HALT)
    try:
        assert read(c, 204, 4) == ("ok", 1), "one entry: the power-on event"
        assert read(c, 201, 1) == ("ok", 0x3D)
        cycle_until(c, hold, lambda s: (s["scon"], s["spos"]) == (0x13, 0x05), what="enabled")
        start_record(c, 1, lambda s: s["scon"] & SCON_FAULT, "fault 28h")
        assert read(c, 204, 4, hold) == ("ok", 2)
        assert read(c, 200, 1, hold) == ("ok", 0x01), "newest entry: a new fault"
        assert read(c, 201, 1, hold) == ("ok", HOMING_REQUIRED)
        _, t_fault = read(c, 202, 1, hold)
        _, t_power_on = read(c, 202, 2, hold)
        assert t_fault > t_power_on, (t_fault, t_power_on)
        assert read(c, 201, 2, hold) == ("ok", 0x3D), "the power-on entry moved to sub 2"
        acknowledge(c)
        assert read(c, 200, 1, hold) == ("ok", 0x00), "the fault has gone"
        assert read(c, 201, 1, hold) == ("ok", HOMING_REQUIRED)
        assert read(c, 204, 4, hold) == ("ok", 3)
        assert write(c, 204, 3, 1, hold) == ("ok", 1)
        # Cleared; the clear itself is the new first entry (3Dh).
        assert read(c, 204, 4, hold) == ("ok", 1)
        assert read(c, 201, 1, hold) == ("ok", 0x3D)
        assert read(c, 201, 2, hold) == ("ok", 0xFFFF), "invalid entry"
    finally:
        c.close()
