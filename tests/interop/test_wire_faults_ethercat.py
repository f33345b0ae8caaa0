"""Faults on an EtherCAT chain's wire through the API: SOEM (pysoem) over a
veth pair finds the twin's slave; with the chain's cable cut it finds none (every frame lost),
nor with its frames corrupted (the Ethernet FCS discards them); mended, it finds it again.
The twin runs in the veth's network namespace, so the API is called from inside it."""

from __future__ import annotations

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
