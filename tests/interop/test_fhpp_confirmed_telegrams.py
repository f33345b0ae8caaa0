"""A confirmed write has been taken (DESIGN "never faster, never stricter than the device"):
FHPP telegrams written back to back, each after its Modbus answer and with no pause, all take
effect on the CMMO-ST; 20 runs of 20 end at the target of a move started by a START pulse
within the burst. The controlwords of the CiA 402 drives over SDO, the CI terminal, RS232 and
Modbus RTU are the field corpus's (`field/test_field_*.py`).

The drive is polled only to learn the outcome, as field code waits for a status."""

from __future__ import annotations

from conftest import wait_until
from test_fhpp_modbus import CCON_DIRECT_ENABLED, CPOS_HALT, CPOS_START, SPOS_MC, cmmo, decode, \
    enable_and_home, telegram  # noqa: F401 (cmmo is a fixture)

RUNS = 20


def test_fhpp_telegrams_back_to_back(cmmo):
    """A PLC that disables, enables and pulses START (set, then taken away) with one Modbus
    write each, no pause: every run moves to its target."""
    twin = cmmo()
    c = twin.client()
    try:
        enable_and_home(c)
        for run in range(RUNS):
            target = 9000 * (1 + run % 2)
            for regs in (telegram(0, 0),
                         telegram(CCON_DIRECT_ENABLED, CPOS_HALT, 0, 50, target),
                         telegram(CCON_DIRECT_ENABLED, CPOS_HALT | CPOS_START, 0, 50, target),
                         telegram(CCON_DIRECT_ENABLED, CPOS_HALT, 0, 50, target)):
                assert not c.write_registers(0, regs).isError()

            def at_target():
                s = decode(c.read_holding_registers(0, count=4).registers)
                return s["spos"] & SPOS_MC and abs(s["actual"] - target) <= 180 and s
            wait_until(at_target, 5.0, what=f"run {run}: at {target} SINC")
    finally:
        c.close()
