"""A chain of real size: `examples/ethercat-64.toml` (64 CMMP-AS on one interface) under SOEM
(pysoem) over a veth pair, with distributed clocks. SOEM counts 64 slaves, maps each
with CSP (RxPDO3 controlword + target, TxPDO3 statusword + position), brings all to Op on
SYNC0, checks the working counter of every cycle, enables every drive and has each follow its
own ramp of CSP set-points. Pulling the cable after slave 32 leaves 32 on the line.

ETHERCAT_64_SECONDS sets the length of the CSP run (default 2 s), ETHERCAT_64_CYCLE_NS the DC
cycle (default 10 ms; the long form, `scripts/ethercat-64`, runs 10 s at 1 ms). Needs root and `ip`; skips otherwise.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import time
from pathlib import Path

import pytest

from conftest import ecat_twin_run, free_port

pysoem = pytest.importorskip("pysoem", reason="pysoem is not installed (pip install pysoem)")

# Opt-in (the test command and scripts/ethercat-64 set it): on a machine whose two cores are
# shared with builds, the Python master is held off the CPU for tens of ms now and then, and
# the drives report 34-1 (8781h) or 62-5 as the manual says; nothing runs beside it there.
pytestmark = pytest.mark.skipif(os.environ.get("ETHERCAT_64") != "1",
                                reason="the 64-drive chain runs with ETHERCAT_64=1 (scripts/ethercat-64)")

SLAVES = 64
SECONDS = float(os.environ.get("ETHERCAT_64_SECONDS", "2"))
# The test command's run: a 10 ms DC cycle, which a Python master keeps on a loaded machine
# (at 1 ms pysoem misses three SYNC0 cycles in a row within seconds there, and the drives
# report 63-4 / 8781h as the manual says). scripts/ethercat-64 runs 1 ms.
CYCLE_NS = int(os.environ.get("ETHERCAT_64_CYCLE_NS", "10000000"))
# DC (SYNC0) or free run (the frame is the drives' time base, CMMP-AS §2.11 "without DC").
DC = os.environ.get("ETHERCAT_64_DC", "1") == "1"
CYCLE_S = CYCLE_NS / 1e9
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "ethercat-64.toml"


def api_in(ns: str, method: str, url: str, body: dict | None = None) -> tuple[int, dict]:
    args = ["ip", "netns", "exec", ns, "curl", "-s", "-o", "-", "-w", "\n%{http_code}", "-X", method, url]
    if body is not None:
        args += ["-H", "content-type: application/json", "-d", json.dumps(body)]
    r = subprocess.run(args, capture_output=True, text=True, timeout=10)
    text, _, code = r.stdout.rpartition("\n")
    return int(code or 0), json.loads(text) if text else {}


def cell_file(tmp_path: Path) -> Path:
    """The example, or at another cycle the example with each drive's interpolator cycle
    60C2h commissioned to it (the DC cycle must equal it: 0x0036)."""
    if CYCLE_NS == 1_000_000:
        return EXAMPLE
    assert CYCLE_NS % 1_000_000 == 0, "whole milliseconds (60C2h:02 = -3)"
    text = EXAMPLE.read_text().replace(
        'interfaces = ["ethercat"]\n',
        f'interfaces = ["ethercat"]\n[drive.objects]\n"60C2:01" = {CYCLE_NS // 1_000_000}\n')
    path = tmp_path / "ethercat-64.toml"
    path.write_text(text)
    return path


def _csp_pdos(slave) -> None:
    """RxPDO3 (1602h) and TxPDO3 (1A02h) assigned over CoE in Pre-Op, and CSP (6060h = 8)."""
    for index, pdo in ((0x1C12, 0x1602), (0x1C13, 0x1A02)):
        slave.sdo_write(index, 0, bytes([0]))
        slave.sdo_write(index, 1, struct.pack("<H", pdo))
        slave.sdo_write(index, 0, bytes([1]))
    slave.sdo_write(0x6060, 0, bytes([8]))


def test_64_drives_run_in_op_with_dc_and_follow_csp(veth, tmp_path):
    ns = veth[0]
    subprocess.run(["ip", "-n", ns, "link", "set", "lo", "up"], check=True, timeout=10)
    port = free_port()
    with ecat_twin_run(veth, tmp_path, "--config", str(cell_file(tmp_path)), "--http", f"127.0.0.1:{port}",
                       "--busy-poll", realtime=True, slaves=SLAVES) as (master_if, _):
        master = pysoem.Master()
        master.open(master_if)
        try:
            assert master.config_init() == SLAVES
            assert all(s.man == 0x1D for s in master.slaves)
            for s in master.slaves:
                _csp_pdos(s)
            if DC:
                assert master.config_dc(), "distributed clocks"
                for s in master.slaves:
                    s.dc_sync(True, CYCLE_NS)
            master.config_map()
            sizes = [(len(s.output), len(s.input)) for s in master.slaves]
            assert sizes == [(6, 6)] * SLAVES, sizes
            assert master.state_check(pysoem.SAFEOP_STATE, 5_000_000) == pysoem.SAFEOP_STATE
            assert master.expected_wkc == 3 * SLAVES

            targets = [0] * SLAVES

            def cycle(cw: int) -> tuple[int, list[int], list[int]]:
                for s, t in zip(master.slaves, targets):
                    s.output = struct.pack("<Hi", cw, t)
                master.send_processdata()
                wkc = master.receive_processdata(100_000)
                words = [struct.unpack("<Hi", bytes(s.input)) for s in master.slaves]
                return wkc, [w[0] for w in words], [w[1] for w in words]

            master.state = pysoem.OP_STATE
            cycle(0)
            master.write_state()
            # Reading 64 AL states while they differ takes SOEM a round trip per slave, longer
            # than three cycles: the state is read once, after the cycles that carry Op.
            due = time.monotonic()
            for _ in range(int(0.5 / CYCLE_S)):
                cycle(0)
                due += CYCLE_S
                time.sleep(max(0.0, due - time.monotonic()))
            master.read_state()
            assert [s.state for s in master.slaves] == [pysoem.OP_STATE] * SLAVES, \
                [hex(s.al_status) for s in master.slaves]
            _, _, pos = cycle(0)
            targets[:] = pos

            bad_wkc = 0
            cycles = 0
            for cw, want in ((0x06, 0x21), (0x07, 0x23), (0x0F, 0x27)):
                for _ in range(500):
                    wkc, sw, pos = cycle(cw)
                    cycles += 1
                    bad_wkc += wkc != master.expected_wkc
                    if all(w & 0x6F == want for w in sw):
                        break
                    due += CYCLE_S
                    time.sleep(max(0.0, due - time.monotonic()))
                assert all(w & 0x6F == want for w in sw), (
                [hex(w) for w in sw[:4]], hex(struct.unpack("<I", master.slaves[0].sdo_read(0x1003, 1)[:4])[0]))
            # Each drive its own ramp: drive k moves k + 1 increments a cycle.
            steps = int(SECONDS / CYCLE_S)
            for _ in range(steps):
                targets[:] = [t + k + 1 for k, t in enumerate(targets)]
                wkc, sw, pos = cycle(0x0F)
                cycles += 1
                bad_wkc += wkc != master.expected_wkc
                due += CYCLE_S
                time.sleep(max(0.0, due - time.monotonic()))
            for _ in range(50):
                wkc, sw, pos = cycle(0x0F)
                bad_wkc += wkc != master.expected_wkc
                due += CYCLE_S
                time.sleep(max(0.0, due - time.monotonic()))
            assert bad_wkc == 0, f"{bad_wkc} wrong working counters in {cycles} cycles"
            if not all(w & 0x6F == 0x27 for w in sw):
                emergencies = []
                master.slaves[0].add_emergency_callback(emergencies.append)
                master.slaves[0].sdo_read(0x6041, 0)
                pytest.fail(f"statuswords {[hex(w) for w in sw[:4]]}, slave 1's EMCYs "
                            f"{[hex(e.error_code) for e in emergencies]}")
            lag = [abs(p - t) for p, t in zip(pos, targets)]
            assert max(lag) < 200, f"followed the set-points: {lag}"
            assert master.read_state() == pysoem.OP_STATE

            status, state = api_in(ns, "POST", f"http://127.0.0.1:{port}/api/ethercat/0/line",
                                   {"action": "pull-cable", "after": 32})
            assert status == 200 and state["reached"] == 32, state
            wkc, _, _ = cycle(0x0F)
            assert wkc == 3 * 32, "the working counter of 32 slaves"
        finally:
            master.close()
