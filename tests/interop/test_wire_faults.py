"""Faults on the wire through the web console's API, seen by a master on
socketcand with python-canopen / python-can: a cut cable silences a node's heartbeat and its
heartbeat consumer (a Kinco FD) reports it with EMCY 8130h (CiA 301), then both come back; a
master whose own cable is cut gets no SDO answer; corrupted frames are error frames the nodes
count (their REC) instead of answers; a share of a node's corrupted answers is sent again by
the node (its TEC +8, -1) and the master still gets every one; a pcap trace of the bus is started and stopped."""

from __future__ import annotations

import json
import os
import re
import struct
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from conftest import add_node, cmmp_switches, wait_until, write_cell


def console(twin) -> str:
    line = wait_until(lambda: next((l for l in twin.stdout_lines if l.startswith("web console on ")), None),
                      5.0, what="the 'web console on' line")
    m = re.match(r"web console on (http://127\.0\.0\.1:\d+)/$", line)
    assert m, line
    return m.group(1)


def api(base: str, method: str, path: str, body: dict | None = None) -> tuple[int, object]:
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(base + path, data=data, method=method,
                                 headers={"content-type": "application/json"} if data else {})
    try:
        with urllib.request.urlopen(req, timeout=5) as r:
            text = r.read()
            return r.status, json.loads(text) if text else None
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


@pytest.fixture
def cell(launch, tmp_path):
    """Node 1, a CMMP-AS beating every 100 ms; node 2, a Kinco FD watching it (250 ms); the
    CMMP-AS's DIP7 set to the Kinco's 500 kbit/s."""
    cfg = write_cell(tmp_path / "cell.toml", [("cmmp-as", 1, {"1017:00": 100}, cmmp_switches(1, 500)),
                                              ("kinco-fd3", 2, {"1016:01": 0x000100FA})])
    twin = launch(config=cfg, extra=("--http", "127.0.0.1:0"))
    return twin, console(twin)


def test_a_cut_cable_silences_the_node_and_its_consumer_sends_8130h(cell, connect, eds_files):
    twin, base = cell
    net = connect(twin)
    node1 = add_node(net, 1, eds_files["cmmp-as"])
    node2 = add_node(net, 2, eds_files["kinco-fd3"])
    net.nmt.send_command(0x01)
    node1.nmt.wait_for_heartbeat(timeout=3.0)
    node2.emcy.reset()
    status, fault = api(base, "POST", "/api/wire/bus/0/faults",
                        {"fault": "cable-break", "node": 1, "for": "1500ms"})
    assert status == 201, fault
    assert fault["fault"] == "cable-break" and fault["node"] == 1
    time.sleep(0.15)  # a heartbeat on its way before the cut
    with pytest.raises(Exception, match="(?i)timeout|heartbeat"):
        node1.nmt.wait_for_heartbeat(timeout=0.5)
    wait_until(lambda: any(e.code == 0x8130 for e in node2.emcy.log), 2.0,
               what="the Kinco's heartbeat consumer to report node 1 (CiA 301 EMCY 8130h)")
    # The fault ends by itself: node 1 beats again.
    node1.nmt.wait_for_heartbeat(timeout=4.0)
    status, faults = api(base, "GET", "/api/wire/bus/0/faults")
    assert status == 200 and faults == []


def test_the_masters_cable_cut_and_mended(cell, connect, eds_files):
    import canopen

    twin, base = cell
    net = connect(twin)
    node1 = add_node(net, 1, eds_files["cmmp-as"])
    assert node1.sdo.upload(0x1000, 0)
    status, fault = api(base, "POST", "/api/wire/bus/0/faults", {"fault": "cable-break"})
    assert status == 201, fault
    assert fault["reach"] == "outside"
    timeout, node1.sdo.RESPONSE_TIMEOUT = node1.sdo.RESPONSE_TIMEOUT, 0.5
    with pytest.raises(canopen.SdoCommunicationError):
        node1.sdo.upload(0x1000, 0)
    node1.sdo.RESPONSE_TIMEOUT = timeout
    status, faults = api(base, "DELETE", f"/api/wire/bus/0/faults/{fault['id']}")
    assert status == 200 and faults == []
    assert node1.sdo.upload(0x1000, 0)


def test_corrupted_frames_are_counted_by_the_nodes_not_answered(cell, raw_bus):
    import can

    twin, base = cell
    bus = raw_bus(twin)
    status, fault = api(base, "POST", "/api/wire/bus/0/faults", {"fault": "corrupt", "frames": 20})
    assert status == 201, fault
    request = can.Message(arbitration_id=0x601, data=[0x40, 0x00, 0x10, 0, 0, 0, 0, 0],
                          is_extended_id=False)

    def answer(timeout: float):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = bus.recv(timeout=0.05)
            if m is not None and m.arbitration_id == 0x581:
                return m
        return None

    def counted():
        status, buses = api(base, "GET", "/api/buses")
        errors = {e["node"]: e for e in buses[0]["node_errors"]}
        return errors if 1 in errors and 2 in errors else None

    for _ in range(20):
        bus.send(request)
    # REC +1 per error frame, -1 per good frame since (node 1's heartbeats every 100 ms).
    errors = wait_until(lambda: (e := counted()) and e[1]["rec"] >= 10 and e[2]["rec"] >= 10 and e,
                        2.0, interval=0.005, what="the nodes to count the error frames")
    assert errors[1]["rec"] <= 20 and errors[2]["rec"] <= 20, errors
    assert errors[1]["state"] == "error active"
    assert answer(0.3) is None, "a frame that fails its CRC is no request"
    bus.send(request)
    assert answer(1.0) is not None, "the fault took its twenty frames"


def test_a_share_of_a_nodes_corrupted_answers_is_sent_again(launch, tmp_path, connect, eds_files):
    """Half of node 1's SDO answers (581h) corrupted, four of them: the share is spread evenly
    over the transmissions on the wire, so the first answer passes and each of the next four
    fails its CRC once and passes when the node sends it again (ISO 11898-1 automatic
    retransmission). python-canopen gets every answer; node 1's TEC is +8 per error, -1 per
    good transmission: 4 x 7 = 28, still error active. Node 1 beats no heartbeat, so its
    answers are all it sends."""
    cfg = write_cell(tmp_path / "cell.toml", [("cmmp-as", 1, {"1017:00": 0}, cmmp_switches(1, 500))])
    twin = launch(config=cfg, extra=("--http", "127.0.0.1:0"))
    base = console(twin)
    net = connect(twin)
    node1 = add_node(net, 1, eds_files["cmmp-as"])
    device_type = node1.sdo.upload(0x1000, 0)
    status, fault = api(base, "POST", "/api/wire/bus/0/faults",
                        {"fault": "corrupt", "node": 1, "cob_id": 0x581, "share": 0.5, "frames": 4})
    assert status == 201, fault
    assert fault["fault"] == "corrupt" and fault["share"] == 0.5, fault

    def node1_errors():
        """Node 1's counters; none while both are 0 (the API lists only counting nodes)."""
        status, buses = api(base, "GET", "/api/buses")
        assert status == 200, buses
        return next((e for e in buses[0]["node_errors"] if e["node"] == 1), None)

    assert node1_errors() is None
    # Answers 2 to 5 are each corrupted once, the first passes.
    for _ in range(5):
        assert node1.sdo.upload(0x1000, 0) == device_type
    errors = node1_errors()
    assert errors is not None and errors["tec"] == 4 * (8 - 1), errors
    assert errors["state"] == "error active", errors
    status, faults = api(base, "GET", "/api/wire/bus/0/faults")
    assert status == 200 and faults == [], "the counted fault has taken its four frames"
    # The fault has ended: the next answer passes at once, TEC -1.
    assert node1.sdo.upload(0x1000, 0) == device_type
    assert node1_errors()["tec"] == 4 * (8 - 1) - 1


def test_a_trace_of_the_bus_from_the_api(cell):
    twin, base = cell
    name = f"interop-{os.getpid()}-bus0.pcap"
    status, t = api(base, "POST", "/api/buses/0/trace", {"name": name})
    assert status == 201, t
    path = Path(t["path"])
    assert path.name == name
    time.sleep(0.5)
    status, _ = api(base, "DELETE", "/api/buses/0/trace")
    assert status == 204
    data = path.read_bytes()
    assert data[:4] == bytes.fromhex("d4c3b2a1")
    # Each record: 16-byte pcap header and a 16-byte SocketCAN frame; heartbeats of node 1.
    ids = []
    off = 24
    while off + 32 <= len(data):
        (incl,) = struct.unpack_from("<I", data, off + 8)
        (can_id,) = struct.unpack_from(">I", data, off + 16)
        ids.append(can_id)
        off += 16 + incl
    assert ids.count(0x701) >= 3, ids
    path.unlink()
    status, e = api(base, "DELETE", "/api/buses/0/trace")
    assert status == 404, e


def test_a_scenario_on_the_live_cell_from_the_api(cell):
    """POST /api/scenarios with a scenario's TOML: it runs on the live cell's clock; its
    report names each expectation."""
    twin, base = cell
    text = """
name = "live cable break"
[[step]]
at = "0s"
nmt = "start"
[[step]]
at = "0s"
name = "node 1 beats"
expect_frame = "701"
within = "300ms"
[[step]]
at = "400ms"
fault = "cable-break"
node = 1
for = "600ms"
[[step]]
at = "450ms"
name = "node 2 reports the silence"
node = 2
expect_emcy = 0x8130
within = "500ms"
[[step]]
at = "450ms"
name = "node 1 stays operational (it cannot hear anyone, but it is not stopped)"
expect = "1001:00"
equals = 0
within = "10ms"
"""
    req = urllib.request.Request(base + "/api/scenarios", data=text.encode(), method="POST",
                                 headers={"content-type": "application/toml"})
    with urllib.request.urlopen(req, timeout=5) as r:
        assert r.status == 202
        run = json.loads(r.read())
    assert run["status"] == "running" and run["name"] == "live cable break"

    def done():
        status, r = api(base, "GET", f"/api/scenarios/{run['id']}")
        return r if r["status"] == "done" else None

    result = wait_until(done, 10.0, interval=0.1, what="the scenario to end")
    report = result["report"]
    outcomes = {o["name"]: o["passed"] for o in report["expectations"]}
    assert outcomes == {
        "node 1 beats": True,
        "node 2 reports the silence": True,
        "node 1 stays operational (it cannot hear anyone, but it is not stopped)": True,
    }, report
    assert report["passed"] is True
    status, e = api(base, "GET", "/api/scenarios/x")
    assert status == 400 and "not a run id" in e["error"]
