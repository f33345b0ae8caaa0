"""`drivetwin fhpp …`, the FHPP master commands, against the CMMO-ST twin over Modbus TCP.

Each test starts `drivetwin run --device cmmo-st --modbus 127.0.0.1:PORT`, runs the CLI commands
against it (each one connection, cyclic FC 0x17), and checks what they print and then what
pymodbus (a client nobody here wrote) reads from the drive afterwards: the reference status
values of the FHPP manual's extract kept beside the project (spec/cmmo-st-fhpp.md §4.3) and the
position in SINC.
"""

from __future__ import annotations

import json
import struct
import time

from conftest import HOST, run_cli
from test_fhpp_modbus import SPOS_ACK, SPOS_MC, SPOS_REF, cmmo, decode  # noqa: F401 (fixture)

EXIT_LINK, EXIT_TIMEOUT, EXIT_REFUSED, EXIT_FAULT = 3, 4, 5, 7
POSITION_WINDOW = 180  # PNU 1022 position target window, SINC


def fhpp(twin, *args, timeout=30.0):
    return run_cli("fhpp", *args, "--modbus", f"{HOST}:{twin.port}", timeout=timeout)


def fhpp_json(twin, *args):
    r = fhpp(twin, *args, "--json")
    assert r.returncode == 0, (r.returncode, r.stdout, r.stderr)
    return json.loads(r.stdout)


def read_inputs(twin):
    """The input telegram and the FC 0x07 fault number, read by pymodbus."""
    c = twin.client()
    try:
        rr = c.read_holding_registers(0, count=4)
        assert not rr.isError(), rr
        status = c.read_exception_status()
        assert not status.isError(), status
        s = decode(rr.registers)
        s["fault"] = status.status
        return s
    finally:
        c.close()


def test_status_decodes_the_power_on_bytes_and_writes_nothing(cmmo):
    twin = cmmo()
    r = fhpp(twin, "status")
    assert r.returncode == 0, r.stderr
    # FHPP-CB-01: power-on SCON 10h (VLOAD), SPOS 04h (MC).
    assert "S2 drive disabled, record selection" in r.stdout
    assert "SCON 10h VLOAD (0001.0000)" in r.stdout
    assert "SPOS 04h MC (0000.0100)" in r.stdout
    s = fhpp_json(twin, "status")
    assert (s["scon"], s["spos"], s["fault"]) == (0x10, 0x04, None), s
    assert s["scon_bits"] == "VLOAD (0001.0000)"
    assert (read_inputs(twin)["scon"], read_inputs(twin)["spos"]) == (0x10, 0x04)


def test_enable_home_move_record_disable(cmmo):
    twin = cmmo()
    # FHPP-CB-03 (FHPP-ST-01, FHPP-ST-02): enabled in record selection → SCON 13h, SPOS 05h.
    s = fhpp_json(twin, "enable")
    assert (s["scon"], s["spos"], s["state"]) == (0x13, 0x05, "S4 operation enabled"), s
    i = read_inputs(twin)
    assert (i["scon"], i["spos"], i["fault"]) == (0x13, 0x05, 0), i

    s = fhpp_json(twin, "home")  # FHPP-CB-08, FHPP-CB-09, FHPP-CB-10
    assert s["spos"] & (SPOS_REF | SPOS_MC) == SPOS_REF | SPOS_MC and not s["spos"] & SPOS_ACK, s
    assert "REF" in s["spos_bits"] and "MC" in s["spos_bits"]
    assert read_inputs(twin)["spos"] & SPOS_REF

    # FHPP-CB-14: direct mode, absolute 27000 SINC (270° with the default 0.01° SINC).
    s = fhpp_json(twin, "move", "27000")
    assert s["mode"] == "direct" and s["scon"] == 0x53, s
    assert abs(s["actual"] - 27000) <= POSITION_WINDOW, s
    i = read_inputs(twin)
    assert i["scon"] == 0x53 and i["spos"] & SPOS_MC and not i["spos"] & SPOS_ACK, i
    assert abs(i["actual"] - 27000) <= POSITION_WINDOW, i

    # Relative −9000 at 50 %: CDIR.ABS = 1, mirrored in SDIR.ABS.
    s = fhpp_json(twin, "move", "-9000", "--relative", "--velocity", "50")
    assert s["byte3"] & 0x01 and s["byte_bits"].startswith("ABS"), s
    i = read_inputs(twin)
    assert abs(i["actual"] - 18000) <= 2 * POSITION_WINDOW, i

    # FHPP-CB-11, FHPP-CB-12, FHPP-CB-13: record 1 (the personality's default record list: target 0 SINC).
    s = fhpp_json(twin, "record", "1")
    assert s["mode"] == "record selection" and s["scon"] == 0x13 and s["byte3"] == 1, s
    i = read_inputs(twin)
    assert i["scon"] == 0x13 and i["byte3"] == 1 and i["spos"] & SPOS_MC, i
    assert abs(i["actual"]) <= POSITION_WINDOW, i

    r = fhpp(twin, "disable")
    assert r.returncode == 0, r.stderr
    assert "S2 drive disabled" in r.stdout
    i = read_inputs(twin)
    assert i["scon"] == 0x10 and i["spos"] & SPOS_REF, i


def test_refused_fault_and_timeout_have_distinct_exit_codes(cmmo):
    twin = cmmo()
    # Not enabled: the master refuses before starting anything.
    r = fhpp(twin, "move", "1000")
    assert r.returncode == EXIT_REFUSED, (r.returncode, r.stderr)
    assert "refused" in r.stderr and "not in S4" in r.stderr
    # FHPP-ST-08: enabled but not referenced, the drive refuses the start with fault 28h.
    fhpp_json(twin, "enable")
    r = fhpp(twin, "move", "1000")
    assert r.returncode == EXIT_FAULT, (r.returncode, r.stderr)
    assert "fault 28h homing required" in r.stderr
    assert read_inputs(twin)["fault"] == 0x28
    # `enable` acknowledges it (T9 then T2, T3); the drive stays in direct mode (53h).
    s = fhpp_json(twin, "enable")
    assert (s["scon"], s["fault"]) == (0x53, None), s
    fhpp_json(twin, "home")
    # A record number above 64: fault 3Fh record invalid.
    r = fhpp(twin, "record", "70")
    assert r.returncode == EXIT_FAULT, (r.returncode, r.stderr)
    assert "fault 3Fh record invalid" in r.stderr
    fhpp_json(twin, "enable")
    # A long move with a short timeout.
    r = fhpp(twin, "move", "3600000", "--velocity", "5", "--timeout-ms", "100")
    assert r.returncode == EXIT_TIMEOUT, (r.returncode, r.stderr)
    assert "motion complete" in r.stderr and "not reached" in r.stderr
    # Nobody listening.
    r = run_cli("fhpp", "status", "--modbus", f"{HOST}:1")
    assert r.returncode == EXIT_LINK, (r.returncode, r.stderr)


def test_one_connection_at_a_time(cmmo):
    twin = cmmo()
    c = twin.client()
    try:
        assert not c.read_holding_registers(0, count=4).isError()
        r = fhpp(twin, "status")
        assert r.returncode == EXIT_LINK, (r.returncode, r.stderr)
        assert "one Modbus client at a time" in r.stderr
    finally:
        c.close()
    time.sleep(0.1)
    assert fhpp(twin, "status").returncode == 0


def test_the_cycle_keeps_the_watchdog_quiet_during_a_long_move(cmmo):
    # FHPP-MB-08: watchdog 250 ms; the move takes over a second, the master exchanges every 10 ms.
    twin = cmmo("--modbus-timeout-ms", "250")
    fhpp_json(twin, "enable")
    fhpp_json(twin, "home")
    t0 = time.monotonic()
    s = fhpp_json(twin, "move", "36000", "--velocity", "5", "--cycle-ms", "10")
    assert time.monotonic() - t0 > 4 * 0.25
    assert abs(s["actual"] - 36000) <= POSITION_WINDOW and s["fault"] is None, s
    i = read_inputs(twin)
    assert i["fault"] == 0 and i["scon"] == 0x53, i


def fpc_read_by_pymodbus(twin, pnu, sub):
    """The EFPC job done by pymodbus itself (FC 0x17, 8 registers, FHPP-MB-04): zero request,
    read request (FPCC 16h), wait for FPCS 15h, zero request (App. C.3.2, FHPP-FPC-01, FHPP-FPC-02)."""
    c = twin.client()

    def cycle(fpc):
        regs = [0x0000, 0x0000, 0x0000, 0x0000, *struct.unpack(">4H", fpc)]
        rr = c.readwrite_registers(read_address=0, read_count=8, write_address=0, values=regs)
        assert not rr.isError(), rr
        return struct.pack(">4H", *rr.registers[4:])

    def until(fpc, pred):
        deadline = time.monotonic() + 2
        while time.monotonic() < deadline:
            got = cycle(fpc)
            if pred(got):
                return got
            time.sleep(0.005)
        raise AssertionError(f"no FPC answer to {fpc.hex()}: {got.hex()}")

    try:
        zero = bytes([0x10, 0, 0, 0, 0, 0, 0, 0])
        until(zero, lambda f: f[0] & 0x0F == 0)
        got = until(struct.pack(">BBHI", 0x16, sub, pnu, 0), lambda f: f[0] in (0x15, 0x17))
        until(zero, lambda f: f[0] & 0x0F == 0)
        assert got[0] == 0x15, got.hex()
        return struct.unpack(">i", got[4:])[0]
    finally:
        c.close()


def test_pnu_read_and_write_through_the_parameter_channel(cmmo):
    twin = cmmo()
    # Write record 2's target (PNU 404:2, int32) negative: pymodbus reads it back itself.
    v = fhpp_json(twin, "pnu", "write", "404:2", "-12345")
    assert (v["pnu"], v["sub"], v["type"], v["value"]) == (404, 2, "INTEGER32", "-12345"), v
    assert v["pwe"] == 0xFFFFCFC7
    assert fpc_read_by_pymodbus(twin, 404, 2) == -12345
    r = fhpp(twin, "pnu", "read", "404:2")
    assert r.returncode == 0 and r.stdout.strip().endswith("= -12345"), (r.stdout, r.stderr)
    # The record then runs to the written target; PNU 1041 agrees with the cyclic position.
    fhpp_json(twin, "enable")
    fhpp_json(twin, "home")
    s = fhpp_json(twin, "record", "2")
    assert s["byte3"] == 2 and abs(s["actual"] + 12345) <= POSITION_WINDOW, s
    i = read_inputs(twin)
    assert abs(i["actual"] + 12345) <= POSITION_WINDOW, i
    v = fhpp_json(twin, "pnu", "read", "1041")
    assert int(v["value"]) == i["actual"], (v, i)
    # Tab. C.7 errors end with exit code 5 and the manual's text.
    for args, text in [(("read", "9999"), "illegal PNU (0x00)"),
                       (("read", "1041:0"), "wrong subindex (0x03)"),
                       (("write", "101:1", "1"), "parameter value cannot be changed (0x01)")]:
        r = fhpp(twin, "pnu", *args)
        assert r.returncode == EXIT_REFUSED, (args, r.returncode, r.stderr)
        assert text in r.stderr, (args, r.stderr)
    # A value outside the type is a usage error, nothing is sent.
    r = fhpp(twin, "pnu", "write", "127:2", "256")
    assert r.returncode == 2, (r.returncode, r.stderr)
    # The channel was left idle: the cyclic telegram still works for the next master.
    assert read_inputs(twin)["fault"] == 0
