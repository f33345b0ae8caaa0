"""The faults of a real EtherCAT line, through the API, met by SOEM (pysoem) and by
`drivetwin ecat` over a veth pair: a chain of three CMMP-AS with the cable pulled behind the
first (the master counts one slave and the working counter drops to one slave's; the two
behind time out on their SM watchdog, fall to Safe-Op with 0x001B and their drives fault with
62-5), plugged back (three found, acknowledged, back in Op); meanwhile the first slave's DL
status shows its port 1 without a link and its loop closed, to SOEM and to `drivetwin ecat
scan`; a slave powered off (it and the one behind it vanish) and on (it is in Init), to SOEM
and to `drivetwin ecat scan`; a DC drift of 50 ppm on the second slave that SOEM's cyclic
system-time distribution corrects (0x092C holds the difference each cycle found, 0x0920 the
corrections).

The twin runs in the veth's network namespace; the API is called from inside it. Needs root
and `ip`; skips otherwise.
"""

from __future__ import annotations

import json
import struct
import subprocess
import threading
import time

import pytest

from conftest import ecat_twin_run, free_port, run_cli, write_cell

pysoem = pytest.importorskip("pysoem", reason="pysoem is not installed (pip install pysoem)")

CYCLE_S = 0.001
# DL status 0x0110 (ETG.1000.4): port 1's link bit and its loop bit (1: closed).
LINK_PORT_1 = 0x0020
LOOP_PORT_1 = 0x0400


def dl_status(slave) -> int:
    """DL status 0x0110 of a pysoem slave, read with an FPRD."""
    return struct.unpack("<H", slave._fprd(0x0110, 2, 100_000))[0]


def api_in(ns: str, method: str, url: str, body: dict | None = None) -> tuple[int, dict]:
    """curl inside the namespace `ns`: (status, JSON body)."""
    args = ["ip", "netns", "exec", ns, "curl", "-s", "-o", "-", "-w", "\n%{http_code}", "-X", method, url]
    if body is not None:
        args += ["-H", "content-type: application/json", "-d", json.dumps(body)]
    r = subprocess.run(args, capture_output=True, text=True, timeout=10)
    text, _, code = r.stdout.rpartition("\n")
    return int(code or 0), json.loads(text) if text else {}


@pytest.fixture
def line3(veth, tmp_path):
    """Three CMMP-AS on one chain with the console inside the namespace: (master interface,
    a function that changes the line and returns its state)."""
    ns = veth[0]
    subprocess.run(["ip", "-n", ns, "link", "set", "lo", "up"], check=True, timeout=10)
    port = free_port()
    cell = write_cell(tmp_path / "chain.toml", [("cmmp-as", n, {}) for n in (1, 2, 3)])
    url = f"http://127.0.0.1:{port}/api/ethercat/0/line"

    def line(body: dict | None = None) -> dict:
        status, state = api_in(ns, "POST" if body else "GET", url, body)
        assert status == 200, state
        return state

    with ecat_twin_run(veth, tmp_path, "--config", str(cell), "--http", f"127.0.0.1:{port}",
                       slaves=3) as (master_if, _):
        yield master_if, line


def cycle(master, n: int) -> list[int]:
    """`n` process-data cycles of 1 ms; their working counters."""
    wkcs = []
    for _ in range(n):
        master.send_processdata()
        wkcs.append(master.receive_processdata(100_000))
        time.sleep(CYCLE_S)
    return wkcs


def while_cycling(master, change):
    """`change()` (an API call, which may take longer than the SM watchdog) on a thread while
    the master keeps its 1 ms cycle, as a PLC does while someone pulls a cable: (its result,
    the working counters of the cycles meanwhile)."""
    done = []
    t = threading.Thread(target=lambda: done.append(change()))
    t.start()
    wkcs = []
    while t.is_alive():
        wkcs += cycle(master, 1)
    t.join()
    return done[0], wkcs


def to_op(master) -> None:
    master.state = pysoem.OP_STATE
    master.send_processdata()
    master.receive_processdata(100_000)
    master.write_state()
    for _ in range(200):
        cycle(master, 1)
        if master.read_state() == pysoem.OP_STATE:
            return
    pytest.fail(f"Op: {[hex(s.state) for s in master.slaves]}")


def test_a_pulled_cable_cuts_off_the_slaves_behind_and_plugged_back_they_return(line3):
    master_if, line = line3
    master = pysoem.Master()
    master.open(master_if)
    try:
        assert master.config_init() == 3
        assert [dl_status(s) for s in master.slaves] == [0x5A33, 0x5A33, 0x5613], "ports 0 and 1 linked"
        assert master.config_map() > 0
        assert master.state_check(pysoem.SAFEOP_STATE, 2_000_000) == pysoem.SAFEOP_STATE
        to_op(master)
        full = master.expected_wkc
        assert full == 9, "3 slaves × (outputs 2 + inputs 1)"
        assert cycle(master, 20) == [full] * 20

        state, wkcs = while_cycling(master, lambda: line({"action": "pull-cable", "after": 1}))
        assert (state["reached"], state["cable_pulled_after"]) == (1, 1), state
        assert set(wkcs) <= {full, 3}, wkcs
        # 150 cycles (the watchdog is 100 ms): every one returns from the first slave alone.
        assert cycle(master, 150) == [3] * 150
        # The first slave's port 1 has lost its link and closed its loop (DL status 0x0110).
        first = dl_status(master.slaves[0])
        assert (first & LINK_PORT_1, first & LOOP_PORT_1) == (0, LOOP_PORT_1), hex(first)

        state, wkcs = while_cycling(master, lambda: line({"action": "plug-cable"}))
        # Back on the line, the two in Safe-Op count their SM2 write and SM3 read again.
        assert set(wkcs) <= {3, full}, wkcs
        assert state["reached"] == 3
        assert state["al_states"] == [8, 4, 4], state
        first = dl_status(master.slaves[0])
        assert (first & LINK_PORT_1, first & LOOP_PORT_1) == (LINK_PORT_1, 0), hex(first)
        master.read_state()
        assert master.slaves[0].state == pysoem.OP_STATE
        for s in master.slaves[1:]:
            assert s.state == pysoem.SAFEOP_STATE | pysoem.STATE_ERROR, hex(s.state)
            assert s.al_status == 0x001B, f"SM watchdog: {s.al_status:#x}"
            # 62-5 "EtherCAT: faulty cyclic data transfer" (no CiA code: 1000h) as a CoE
            # emergency, and the drive in FAULT.
            emergencies = []
            s.add_emergency_callback(emergencies.append)
            sw = int.from_bytes(s.sdo_read(0x6041, 0), "little")
            assert sw & 0x08, f"fault (reaction active or fault): statusword {sw:#06x}"
            assert [e.error_code for e in emergencies] == [0x1000], emergencies
        for s in master.slaves[1:]:
            s.state = pysoem.SAFEOP_STATE | pysoem.STATE_ACK
            s.write_state()
        cycle(master, 1)
        assert master.read_state() == pysoem.SAFEOP_STATE, [hex(s.state) for s in master.slaves]
        to_op(master)
        assert cycle(master, 20) == [full] * 20
    finally:
        master.close()


def test_drivetwin_ecat_scan_shows_where_the_line_is_cut(line3):
    master_if, line = line3

    def scan() -> dict:
        r = run_cli("ecat", "scan", "-i", master_if, "--json")
        assert r.returncode == 0, r.stderr
        return json.loads(r.stdout)

    j = scan()
    assert j["count"] == 3, j
    assert [[p["link"] for p in s["ports"]] for s in j["slaves"]] == [[True, True], [True, True], [True, False]]
    line({"action": "pull-cable", "after": 1})
    j = scan()
    assert j["count"] == 1, j
    (first,) = j["slaves"]
    assert first["ports"][1] == {"port": 1, "link": False, "loop_closed": True, "communication": False}, first
    r = run_cli("ecat", "scan", "-i", master_if)
    assert "0:up 1:down" in r.stdout and "1 slave(s)" in r.stdout, r.stdout
    line({"action": "plug-cable"})
    j = scan()
    assert j["count"] == 3, j
    assert j["slaves"][0]["ports"][1]["link"] is True, j


def test_drivetwin_ecat_sees_a_slave_powered_off_and_back_in_init(line3):
    master_if, line = line3

    def ecat_json(*args: str) -> dict | list:
        r = run_cli("ecat", *args, "-i", master_if, "--json")
        assert r.returncode == 0, r.stderr
        return json.loads(r.stdout)

    ecat_json("state", "preop")
    assert [s["state"] for s in ecat_json("scan")["slaves"]] == ["PREOP"] * 3
    line({"action": "power-off", "slave": 1})
    j = ecat_json("scan")
    assert j["count"] == 1, "slave 1 and the one behind it are off the line"
    assert j["slaves"][0]["ports"][1]["link"] is False, j
    line({"action": "power-on", "slave": 1})
    j = ecat_json("scan")
    assert j["count"] == 3, j
    # Switched on, slave 1 starts in Init; the others kept their power and their state.
    assert [s["state"] for s in j["slaves"]] == ["PREOP", "INIT", "PREOP"], j


def test_a_slave_powered_off_vanishes_and_comes_back_in_init(line3):
    master_if, line = line3
    master = pysoem.Master()
    master.open(master_if)
    try:
        assert master.config_init() == 3  # SOEM leaves them in Pre-Op
        assert line()["al_states"] == [2, 2, 2]
        state = line({"action": "power-off", "slave": 1})
        assert (state["reached"], state["powered_off"]) == (1, [1]), state
        assert master.config_init() == 1, "slave 1 and the one behind it are gone"
        state = line({"action": "power-on", "slave": 1})
        assert state["reached"] == 3
        assert state["al_states"][1] == 1, f"Init after power-on: {state}"
        assert master.config_init() == 3
        assert [s.man for s in master.slaves] == [0x1D] * 3
    finally:
        master.close()


def test_a_drifting_clock_is_corrected_by_soems_dc_distribution(line3):
    master_if, line = line3
    master = pysoem.Master()
    master.open(master_if)
    try:
        assert master.config_init() == 3
        assert master.config_dc(), "distributed clocks"
        assert master.config_map() > 0
        assert master.state_check(pysoem.SAFEOP_STATE, 2_000_000) == pysoem.SAFEOP_STATE
        second = master.slaves[1]

        def difference() -> int:
            """0x092C as a signed number (bit 31: the local copy was ahead)."""
            raw = struct.unpack("<I", second._fprd(0x092C, 4, 100_000))[0]
            return -(raw & 0x7FFF_FFFF) if raw & 0x8000_0000 else raw

        def offset() -> int:
            return struct.unpack("<q", second._fprd(0x0920, 8, 100_000))[0]

        cycle(master, 50)
        assert difference() == 0, "a nominal clock needs no correction"
        state = line({"action": "clock", "slave": 1, "drift_ppm": 50})
        assert state["clocks"] == [{"slave": 1, "drift_ppm": 50.0, "jitter_ns": 0}], state
        before, t0 = offset(), time.monotonic_ns()
        cycle(master, 300)
        after, t1 = offset(), time.monotonic_ns()
        # Each cycle's FRMW finds the clock ahead by 50 ppm of the cycle (≥ 50 ns at 1 ms).
        d = difference()
        assert -50 * 20 <= d <= -40, f"0x092C {d} ns"
        # The offset took back what the clock gained: 50 ppm of the time between the reads.
        gained = (t1 - t0) * 50e-6
        assert abs((before - after) - gained) < 0.3 * gained + 200, (before - after, gained)
    finally:
        master.close()
