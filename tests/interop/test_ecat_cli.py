"""`drivetwin ecat scan|state|sdo`, drivetwin's own minimal EtherCAT master, against the twin.

`drivetwin run --ethercat dtwA…` runs inside a private network namespace on one end of a veth
pair (the fixture pattern of test_ethercat.py); the CLI opens the other end. Checked: the scan
(slave count from the BRD working counter, station addresses 0x1000 + n, Festo vendor 0x1D,
the product code of `drivetwin esi`, the links of ports 0 and 1), the AL state ladder Init → Pre-Op → Safe-Op → Op → Init
and a refused transition with its AL status code, CoE SDO read/write and an abort, a chain of
two twins, and cross-checks with SOEM (pysoem) in both directions.

Needs root (network namespaces, raw sockets) and `ip` (iproute2); skips with a message
otherwise.
"""

from __future__ import annotations

import contextlib
import json
import subprocess
import time

import pytest

from conftest import ecat_twin_run, product_code, run_cli, write_cell

FESTO = 0x1D


@pytest.fixture
def chain(veth, tmp_path):
    """Starts `drivetwin run --ethercat` with `slaves` CMMP-AS drives; returns the master-side
    interface. The twins stop (and are checked) at teardown."""
    with contextlib.ExitStack() as running:

        def _start(slaves: int = 1) -> str:
            extra = []
            if slaves > 1:
                cell = write_cell(tmp_path / "chain.toml",
                                  [("cmmp-as", n, {}) for n in range(1, slaves + 1)])
                extra = ["--config", str(cell)]
            master_if, _ = running.enter_context(
                ecat_twin_run(veth, tmp_path, *extra, slaves=slaves))
            return master_if

        yield _start


def ecat(*args: str, expect: int = 0) -> subprocess.CompletedProcess:
    r = run_cli("ecat", *args)
    assert r.returncode == expect, f"drivetwin ecat {' '.join(args)}: exit {r.returncode}\n{r.stdout}\n{r.stderr}"
    return r


def ecat_json(*args: str, expect: int = 0):
    return json.loads(ecat(*args, "--json", expect=expect).stdout)


def test_scan_finds_one_festo_drive(chain):
    iface = chain(1)
    j = ecat_json("scan", "-i", iface)
    assert j["count"] == 1, j
    (s,) = j["slaves"]
    assert s["slave"] == 1 and s["station"] == 0x1001
    assert s["vendor_id"] == FESTO
    assert s["product_code"] == product_code()
    assert s["name"].startswith("CMMP-AS"), s
    assert (s["state"], s["error"], s["al_status_code"]) == ("INIT", False, 0)
    text = ecat("scan", "-i", iface).stdout
    assert "0x1001" in text and "0x0000001d" in text and "1 slave(s)" in text, text


def test_state_ladder_and_a_refused_transition(chain):
    iface = chain(1)
    # Init → Safe-Op skips Pre-Op: refused with 0x0011, exit code 1, the slave stays in Init.
    r = ecat("state", "-i", iface, "safeop", expect=1)
    assert "INIT -> SAFEOP refused" in r.stderr, r.stderr
    assert "0x0011: Invalid requested state change" in r.stderr, r.stderr
    (s,) = ecat_json("state", "-i", iface)
    assert (s["state"], s["error"], s["al_status_code"]) == ("INIT", True, 0x11), s
    assert s["al_status_text"] == "Invalid requested state change"
    # The ladder; each request acknowledges the error first.
    for target, name in [("preop", "PREOP"), ("safeop", "SAFEOP"), ("op", "OP")]:
        (s,) = ecat_json("state", "-i", iface, target)
        assert (s["requested"], s["state"], s["error"]) == (name, name, False), s
    # Op holds with no cyclic process data (this master switches the SM watchdog off).
    time.sleep(0.5)
    assert ecat("state", "-i", iface).stdout.strip() == "slave 1 (0x1001): OP"
    # Op → Init directly is allowed (every downward transition is).
    r = ecat("state", "-i", iface, "--slave", "1", "init")
    assert r.stdout.strip() == "slave 1 (0x1001): OP -> INIT", r.stdout
    # Pre-Op → Op skips Safe-Op: refused, JSON says so too.
    ecat("state", "-i", iface, "preop")
    (s,) = ecat_json("state", "-i", iface, "op", expect=1)
    assert (s["requested"], s["state"], s["error"], s["al_status_code"]) == ("OP", "PREOP", True, 0x11), s
    # A slave that is not there.
    r = ecat("state", "-i", iface, "--slave", "2", expect=2)
    assert "no slave 2 on the wire (1 found)" in r.stderr, r.stderr


def test_sdo_read_write_and_abort(chain):
    iface = chain(1)
    # The slave starts in Init; `sdo` takes it to Pre-Op for the mailbox.
    assert ecat("sdo", "read", "-i", iface, "--slave", "1", "0x1018:1").stdout.strip() == str(FESTO)
    j = ecat_json("sdo", "read", "-i", iface, "0x1018:02")
    assert (j["index"], j["sub"], j["value"]) == ("0x1018", 2, product_code()), j
    # A writable object: the following error window 6065h (u32).
    ecat("sdo", "write", "-i", iface, "0x6065:0", "12345", "--type", "u32")
    assert ecat("sdo", "read", "-i", iface, "0x6065").stdout.strip() == "12345"
    j = ecat_json("sdo", "write", "-i", iface, "6065:00", "54321", "--device", "cmmp-as")
    assert j["written"] == (54321).to_bytes(4, "little").hex().upper(), j
    assert ecat_json("sdo", "read", "-i", iface, "0x6065:0", "--type", "i32")["value"] == 54321
    # A missing object: abort 0602 0000h, exit code 5, the text of CiA 301.
    r = ecat("sdo", "read", "-i", iface, "0x5FFF:0", expect=5)
    assert "abort 0x06020000 (Object does not exist in the object dictionary)" in r.stderr, r.stderr
    j = ecat_json("sdo", "read", "-i", iface, "0x5FFF:0", expect=5)
    assert (j["abort_code"], j["abort_text"]) == ("0x06020000", "Object does not exist in the object dictionary")
    # A read-only object refuses a write: 0601 0002h.
    r = ecat("sdo", "write", "-i", iface, "0x1018:1", "1", "--type", "u32", expect=5)
    assert "0x06010002" in r.stderr, r.stderr


def test_a_chain_of_two_twins(chain):
    iface = chain(2)
    j = ecat_json("scan", "-i", iface)
    assert j["count"] == 2, j
    assert [s["station"] for s in j["slaves"]] == [0x1001, 0x1002]
    # DL status 0x0110: the first slave has links on ports 0 and 1, the last on port 0 alone
    # with its port 1 loop closed (the frame turns round there).
    assert [s["dl_status"] for s in j["slaves"]] == [0x5A33, 0x5613], j
    last_port_1 = j["slaves"][1]["ports"][1]
    assert (last_port_1["link"], last_port_1["loop_closed"]) == (False, True), last_port_1
    text = ecat("scan", "-i", iface).stdout
    assert "0:up 1:up" in text and "0:up 1:down" in text, text
    assert all(s["vendor_id"] == FESTO for s in j["slaves"])
    (s,) = ecat_json("state", "-i", iface, "--slave", "2", "preop")
    assert (s["slave"], s["state"]) == (2, "PREOP")
    states = ecat_json("state", "-i", iface)
    assert [(s["slave"], s["state"]) for s in states] == [(1, "INIT"), (2, "PREOP")]
    # Every slave at once, in line order.
    r = ecat("state", "-i", iface, "preop")
    assert r.stdout.splitlines() == ["slave 1 (0x1001): INIT -> PREOP", "slave 2 (0x1002): PREOP -> PREOP"], r.stdout
    # Each slave has its own dictionary.
    ecat("sdo", "write", "-i", iface, "--slave", "2", "0x6065:0", "777", "--type", "u32")
    assert ecat("sdo", "read", "-i", iface, "--slave", "2", "0x6065:0").stdout.strip() == "777"
    assert ecat("sdo", "read", "-i", iface, "--slave", "1", "0x6065:0").stdout.strip() != "777"
    r = ecat("state", "-i", iface, "init")
    assert r.stdout.splitlines() == ["slave 1 (0x1001): PREOP -> INIT", "slave 2 (0x1002): PREOP -> INIT"], r.stdout


def test_agrees_with_soem(chain):
    """What drivetwin's master writes, SOEM reads, and the other way round."""
    pysoem = pytest.importorskip("pysoem", reason="pysoem is not installed (pip install pysoem)")
    iface = chain(1)
    ecat("sdo", "write", "-i", iface, "0x6065:0", "4242", "--type", "u32")
    master = pysoem.Master()
    master.open(iface)
    try:
        assert master.config_init() == 1
        slave = master.slaves[0]
        assert int.from_bytes(slave.sdo_read(0x6065, 0), "little") == 4242
        slave.sdo_write(0x6065, 0, (2424).to_bytes(4, "little"))
        master.config_map()
        assert master.state_check(pysoem.SAFEOP_STATE, 2_000_000) == pysoem.SAFEOP_STATE
    finally:
        master.close()
    (s,) = ecat_json("state", "-i", iface)
    assert s["state"] == "SAFEOP", s
    # SOEM numbers slaves from 1 too and gave the same station address.
    assert ecat_json("scan", "-i", iface)["slaves"][0]["station"] == 0x1001
    assert ecat("sdo", "read", "-i", iface, "0x6065:0").stdout.strip() == "2424"


def test_nothing_on_the_wire(veth):
    _, _, master_if = veth
    r = ecat("scan", "-i", master_if, "--frame-timeout-ms", "20", expect=3)
    assert "no frame came back" in r.stderr, r.stderr
