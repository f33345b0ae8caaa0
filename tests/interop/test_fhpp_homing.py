"""CMMO-ST homing to a fixed stop over Modbus TCP, driven by pymodbus.

The homing method PNU 1011, the search velocity PNU 1012:1 and the axis zero point offset
PNU 1010 are written through the parameter channel (FC 0x17 with 8 registers, manual App. C),
then CPOS.HOM starts the run (manual §6.2). The twin's default mechanics have the negative
fixed stop 3 motor revolutions below the power-on position (crates/drive/src/vendors/
festo_cmmo_st/axis_mechanics.rs); with the dictionary's default axis 1 revolution = 36000 SINC.
"""

from __future__ import annotations

import time

import pytest

from test_fhpp_modbus import (  # noqa: F401  (cmmo is a fixture)
    CCON_RECORD_ENABLED, CPOS_HALT, CPOS_HOM, SCON_FAULT, SPOS_ACK, SPOS_MC, SPOS_REF, cmmo,
    cycle_until, exchange, telegram)
from conftest import CHANNEL, HOST, add_node, free_port
from pymodbus.client import ModbusTcpClient
from test_fhpp_parameter_channel import read, signed, write

REV = 36_000  # SINC per motor revolution (PNU 1003 default)
STOP = -3 * REV  # the negative fixed stop, raw SINC from the power-on position
AZ_OFFSET = 3_600  # PNU 1010: AZ 36 deg off the stop (manual 6.2.1: back off >= 1 mm)
WINDOW = 180  # PNU 1022 position target window


def test_homing_to_the_negative_fixed_stop(cmmo):
    c = cmmo().client()
    try:
        home_to_the_negative_stop(c, STOP)
    finally:
        c.close()


def home_to_the_negative_stop(c, stop):
    """Method -17 onto the negative fixed stop at `stop` (raw SINC from power-on), then
    checks the drive stands referenced at PZ 0 (AZ = the stop + PNU 1010)."""
    idle = telegram(0, 0)
    # PNU 1011 = -17 (int8, sign-extended in the PWE), read back the same way.
    assert write(c, 1011, 1, -17) == ("ok", 0xFFFFFFEF)
    assert read(c, 1011, 1) == ("ok", 0xFFFFFFEF)
    # PNU 1012:1 is rw2: written with the output stage off. 3 rev/s keeps the run short.
    assert write(c, 1012, 1, 3 * REV) == ("ok", 3 * REV)
    assert write(c, 1010, 1, AZ_OFFSET) == ("ok", AZ_OFFSET)
    s = exchange(c, idle)
    assert (s["scon"], s["spos"]) == (0x10, 0x04), s
    cycle_until(c, telegram(CCON_RECORD_ENABLED, CPOS_HALT),
                lambda s: (s["scon"], s["spos"]) == (0x13, 0x05), what="enabled 13h/05h")
    # HOM: ACK rises, MC falls, REF stays 0 while the run lasts.
    hom = telegram(CCON_RECORD_ENABLED, CPOS_HALT | CPOS_HOM)
    s = cycle_until(c, hom, lambda s: s["spos"] & SPOS_ACK, what="ACK")
    assert not s["spos"] & SPOS_MC and not s["spos"] & SPOS_REF, s
    # Not yet referenced, bytes 5...8 show raw - PNU 1010: follow the axis to the stop.
    lowest = s["actual"]
    deadline = time.monotonic() + 15
    while True:
        s = exchange(c, hom)
        lowest = min(lowest, s["actual"])
        assert not s["scon"] & SCON_FAULT, s
        if s["spos"] & SPOS_MC:
            break
        if time.monotonic() > deadline:
            pytest.fail(f"homing did not complete: {s}")
        time.sleep(0.002)
    assert s["spos"] & SPOS_REF, s
    # It ran into the stop (and no further: the stop is rigid).
    assert abs(lowest - (stop - AZ_OFFSET)) <= 2 * WINDOW, lowest
    # HOM away: ACK falls; the drive stands at AZ = REF + PNU 1010, i.e. at PZ 0.
    s = cycle_until(c, telegram(CCON_RECORD_ENABLED, CPOS_HALT),
                    lambda s: not s["spos"] & SPOS_ACK, what="ACK falls")
    assert s["spos"] & (SPOS_MC | SPOS_REF) == SPOS_MC | SPOS_REF, s
    assert abs(s["actual"]) <= WINDOW, s
    status, actual = read(c, 1041, 1, telegram(CCON_RECORD_ENABLED, CPOS_HALT))
    assert status == "ok" and abs(signed(actual)) <= WINDOW, actual


def test_a_cell_file_sets_the_axis_and_runs_beside_a_canopen_drive(launch, tmp_path, connect,
                                                                    eds_files):
    """One process, one cell file: a CMMP-AS on the CAN bus (python-canopen) and a CMMO-ST on
    its own Modbus port (pymodbus) whose [drive.axis] puts the negative stop at -1.5 rev."""
    port = free_port()
    cell = tmp_path / "cell.toml"
    cell.write_text("\n".join([
        "[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', "",
        "[[drive]]", 'device = "cmmp-as"', "node = 1", "",
        "[[drive]]", 'device = "cmmo-st"', f'modbus = "{HOST}:{port}"',
        "[drive.stepper]", 'mode = "closed-loop"', "load_torque = 0.005",  # below the Coulomb friction: it holds
        "[drive.axis]", "end_stops = [-1.5, 10.0]", 'index_pulse = "none"', "",
    ]))
    twin = launch(config=cell)
    assert f"modbus server on {HOST}:{port}" in twin.stdout_lines, twin.stdout_lines
    net = connect(twin)
    cmmp = add_node(net, 1, eds_files["cmmp-as"])
    assert cmmp.sdo[0x1018][1].raw == 0x1D
    c = ModbusTcpClient(HOST, port=port, timeout=2, retries=0)
    assert c.connect()
    try:
        home_to_the_negative_stop(c, -1.5 * REV)
    finally:
        c.close()
    assert cmmp.sdo[0x1018][1].raw == 0x1D, "the CAN drive is served all along"
