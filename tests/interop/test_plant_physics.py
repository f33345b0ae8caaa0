"""The plant's physics through the REST API of `drivetwin run --http`, seen on the bus by
python-canopen: a hot cabinet heats the CMMP-AS's motor past 6510h:2F and its own
supervision sends EMCY 4310h (03-0) with 6510h:2E showing the temperature; a pulled encoder
cable is EMCY 7380h (08-0); the positive limit switch actuated by name shows in 60FDh bit 1."""

from __future__ import annotations

import json
import urllib.request

from conftest import wait_until
from test_diagnostics import console_url


def put(url: str, body: dict):
    req = urllib.request.Request(url, data=json.dumps(body).encode(), method="PUT",
                                 headers={"content-type": "application/json"})
    with urllib.request.urlopen(req, timeout=5) as r:
        return r.status, json.load(r)


def test_temperature_encoder_and_switch_by_name_over_rest(launch, node_of):
    twin = launch("cmmp-as", 1, extra=("--http", "127.0.0.1:0"))
    url = console_url(twin) + "api/drives/0/"
    node = node_of(twin)
    assert node.sdo[0x6510][0x2E].raw == 25, "the motor at the ambient temperature"

    # The switch by name: DIN7 (E1) with the default 6510h:12 = 0.
    status, _ = put(url + "switches/limit_positive", {"actuated": True})
    assert status == 200
    wait_until(lambda: node.sdo[0x60FD].raw & 0x7 == 0x2, 2.0, what="60FDh bit 1")
    put(url + "switches/limit_positive", {"actuated": None})
    wait_until(lambda: node.sdo[0x60FD].raw & 0x7 == 0, 2.0, what="60FDh released")

    # A hot cabinet, a motor with a short thermal time constant.
    status, p = put(url + "thermal", {"motor_time_constant_s": 0.2})
    assert status == 200, p
    status, p = put(url + "ambient", {"celsius": 110.0})
    assert status == 200 and p["ambient_c"] == 110.0, p
    wait_until(lambda: any(e.code == 0x4310 for e in node.emcy.log), 5.0, what="EMCY 4310h")
    assert node.sdo[0x6510][0x2E].raw >= 100, "6510h:2E shows the hot motor"
    wait_until(lambda: node.sdo[0x6041].raw & 0x4F == 0x08, 2.0, what="FAULT")

    status, p = put(url + "encoder", {"fault": "disconnected"})
    assert status == 200 and p["encoder"] == "disconnected", p
    wait_until(lambda: any(e.code == 0x7380 for e in node.emcy.log), 2.0, what="EMCY 7380h")
