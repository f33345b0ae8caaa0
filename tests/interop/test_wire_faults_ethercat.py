"""Faults on an EtherCAT chain's wire through the API: SOEM (pysoem) over a
veth pair finds the twin's slave; with the chain's cable cut it finds none (every frame lost),
nor with its frames corrupted (the Ethernet FCS discards them); mended, it finds it again.
Lost and corrupted frames at a rate and by a count: SOEM's cyclic exchange misses exactly
those. The twin runs in the veth's network namespace, so the API is called from inside it."""

from __future__ import annotations

import contextlib
import json
import subprocess

import pytest

from conftest import ecat_twin_run, free_port

pysoem = pytest.importorskip("pysoem", reason="pysoem is not installed (pip install pysoem)")


def api_in(ns: str, method: str, url: str, body: dict | None = None) -> tuple[int, str]:
    """curl inside the namespace `ns`: (status, body)."""
    args = ["ip", "netns", "exec", ns, "curl", "-s", "-o", "-", "-w", "\n%{http_code}", "-X", method, url]
    if body is not None:
        args += ["-H", "content-type: application/json", "-d", json.dumps(body)]
    r = subprocess.run(args, capture_output=True, text=True, timeout=10)
    text, _, code = r.stdout.rpartition("\n")
    return int(code or 0), text


def slaves_found(master_if: str) -> int:
    master = pysoem.Master()
    master.open(master_if)
    try:
        return master.config_init()
    finally:
        master.close()


@contextlib.contextmanager
def soem_in_safeop(veth, tmp_path):
    """The twin in the veth's namespace with its console on the namespace's loopback, and SOEM
    with the slave mapped in Safe-Op: (namespace, the chain's faults URL, `answered`), where
    `answered(n)` runs n cyclic exchanges and says whether each frame came back (a lost one
    waits out 100 ms)."""
    ns = veth[0]
    subprocess.run(["ip", "-n", ns, "link", "set", "lo", "up"], check=True, timeout=10)
    port = free_port()
    base = f"http://127.0.0.1:{port}/api/wire/ethercat/0/faults"
    with ecat_twin_run(veth, tmp_path, "--http", f"127.0.0.1:{port}") as (master_if, _lines):
        master = pysoem.Master()
        master.open(master_if)
        try:
            assert master.config_init() == 1
            assert master.config_map() > 0
            assert master.state_check(pysoem.SAFEOP_STATE, 2_000_000) == pysoem.SAFEOP_STATE

            def answered(cycles: int) -> list[bool]:
                out = []
                for _ in range(cycles):
                    master.send_processdata()
                    out.append(master.receive_processdata(100_000) > 0)
                return out

            yield ns, base, answered
        finally:
            master.close()


def test_a_cut_or_corrupted_chain_has_no_slave_for_the_master(veth, tmp_path):
    ns = veth[0]
    # The namespace's loopback, for the console.
    subprocess.run(["ip", "-n", ns, "link", "set", "lo", "up"], check=True, timeout=10)
    port = free_port()
    base = f"http://127.0.0.1:{port}/api/wire/ethercat/0/faults"
    with ecat_twin_run(veth, tmp_path, "--http", f"127.0.0.1:{port}") as (master_if, _lines):
        assert slaves_found(master_if) == 1
        for fault in ({"fault": "cable-break"}, {"fault": "corrupt"}):
            status, text = api_in(ns, "POST", base, fault)
            assert status == 201, text
            assert slaves_found(master_if) <= 0, fault  # SOEM: 0, or -1 (no frame came back)
            status, text = api_in(ns, "DELETE", base)
            assert status == 200 and json.loads(text) == [], text
            assert slaves_found(master_if) == 1, "mended"
        # A delay holds each frame back in the twin; it is still answered.
        status, text = api_in(ns, "POST", base, {"fault": "delay", "delay": "1ms"})
        assert status == 201, text
        status, text = api_in(ns, "DELETE", base)
        assert status == 200, text


def test_a_share_of_lost_frames_and_a_count_of_corrupted_ones_reach_soems_cycle(veth, tmp_path):
    """A loss rate: with half the frames lost (`drop`, share 0.5, spread evenly: every second
    frame) SOEM's cyclic exchange gets every second LRW back, the others never; three
    corrupted frames (the Ethernet FCS discards them) are three cycles without an answer, and
    the cycles after them pass."""
    with soem_in_safeop(veth, tmp_path) as (ns, base, answered):
        assert answered(4) == [True] * 4
        status, text = api_in(ns, "POST", base, {"fault": "drop", "share": 0.5})
        assert status == 201, text
        assert answered(20) == [True, False] * 10, "every second frame lost"
        status, text = api_in(ns, "DELETE", base)
        assert status == 200, text
        assert answered(4) == [True] * 4

        status, text = api_in(ns, "POST", base, {"fault": "corrupt", "frames": 3})
        assert status == 201, text
        assert answered(6) == [False] * 3 + [True] * 3, "three corrupted, then through"
        status, text = api_in(ns, "GET", base)
        assert status == 200 and json.loads(text) == [], "the counted fault has ended"


def test_a_share_of_corrupted_frames_fails_every_second_cycle_of_soem(veth, tmp_path):
    """A corruption rate: with half the frames corrupted (`corrupt`, share 0.5, spread evenly:
    every second frame) the Ethernet FCS discards every second LRW, so SOEM's cyclic exchange
    gets exactly every second one back; the fault list shows the share; a share above 1 is
    refused with the reason."""
    with soem_in_safeop(veth, tmp_path) as (ns, base, answered):
        status, text = api_in(ns, "POST", base, {"fault": "corrupt", "share": 1.5})
        assert status == 400, text
        assert "share 1.5" in text, text
        assert answered(4) == [True] * 4
        status, text = api_in(ns, "POST", base, {"fault": "corrupt", "share": 0.5})
        assert status == 201, text
        fault = json.loads(text)
        assert fault["fault"] == "corrupt" and fault["share"] == 0.5, fault
        assert answered(20) == [True, False] * 10, "every second frame corrupted"
        status, text = api_in(ns, "DELETE", base)
        assert status == 200, text
        assert answered(4) == [True] * 4
