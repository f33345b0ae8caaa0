"""The Kinco FD3's LED panel over the web console's REST API (`drivetwin run --device kinco-fd3
--http`), seen on CANopen with python-canopen: keys walk F003 to d3.47 Jog_RPM and change it
(the SDO upload of 2FF0h:23 reads the new value), then F006 jog (the manual's text kept beside
the project, seeds/001_da459f46c7138f7b.txt §4.3.3: d6.40, ▼ to d6.15, ▲ to d6.25, SET "Jog")
enables the drive and turns the motor while ▲ is held, and stops it on release."""

from __future__ import annotations

import json
import re
import threading
import time
import urllib.request

from conftest import wait_until


def console_url(twin) -> str:
    line = wait_until(lambda: next((l for l in twin.stdout_lines if l.startswith("web console on ")), None),
                      5.0, what="the 'web console on' line")
    m = re.match(r"web console on (http://127\.0\.0\.1:\d+/)$", line)
    assert m, line
    return m.group(1)


def request(url: str, body: dict | None = None) -> dict:
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(url, data=data, method="GET" if body is None else "POST",
                                 headers={"content-type": "application/json"})
    with urllib.request.urlopen(req, timeout=5) as r:
        return json.loads(r.read())


def test_panel_keys_over_http_change_jog_rpm_and_jog_the_motor(launch, node_of):
    twin = launch("kinco-fd3", 1, extra=("--http", "127.0.0.1:0"))
    base = console_url(twin) + "api/drives/0/panel"
    node = node_of(twin)
    # The factory set-up: DIN1 Enable owns the controlword (a bus write of 6040h is refused);
    # the panel's jog runs "independent of other settings" (§4.3.3) all the same.

    def key(k: str, action: str = "click") -> str:
        return request(base + "/keys", {"key": k, "action": action})["text"]

    assert request(base)["text"] == "    0"  # d1.25 Real_Speed_RPM
    for _ in range(3):
        key("mode")
    text = key("set")
    for _ in range(60):
        if text == " d3.47":
            break
        text = key("up")
    assert text == " d3.47"
    assert key("set") == "   30"
    key("mode")  # the tens digit
    key("up")
    assert key("up") == "   50"
    key("set")
    assert node.sdo[0x2FF0][0x23].raw == 50, "the panel's change is the drive's value on CANopen"

    # F006: back to the menu, on to F006, the key check, "Jog".
    assert key("mode").strip() == "F003"
    for _ in range(3):
        key("mode")
    assert key("set") == " d6.40"
    for _ in range(25):
        key("down")
    for _ in range(10):
        text = key("up")
    assert text == " d6.25"
    assert key("set").strip() == "Jog"

    p0 = node.sdo[0x6063].raw
    key("up", "press")
    wait_until(lambda: node.sdo[0x6041].raw & 0x6F == 0x27, 3.0, what="enabled by the panel")
    wait_until(lambda: abs(node.sdo[0x2FF0][0x14].raw - 50) <= 3, 3.0, what="50 rpm")
    assert node.sdo[0x6061].raw == -3
    assert node.sdo[0x2010][3].raw != 0, "DIN1 still has a function"
    time.sleep(0.3)
    assert node.sdo[0x6063].raw > p0, "the motor turned"
    key("up", "release")
    wait_until(lambda: node.sdo[0x6041].raw & 0x6F != 0x27, 3.0, what="disabled on release")
    wait_until(lambda: abs(node.sdo[0x2FF0][0x14].raw) <= 1, 3.0, what="stopped")


def test_panel_ea00_3_reboots_the_drive(launch, node_of):
    """EASY EA00 = 3 (§4.3.1 Tab. 4-2: "reboot the servo drive") over the HTTP panel: the twin
    restarts the drive as after NMT reset node — its boot-up message on CAN, and a value set
    over CANopen and never stored (Jog_RPM 2FF0h:23) back at its default 30."""
    twin = launch("kinco-fd3", 1, extra=("--http", "127.0.0.1:0"))
    base = console_url(twin) + "api/drives/0/panel"
    node = node_of(twin)
    node.sdo[0x2FF0][0x23].raw = 77
    assert node.sdo[0x2FF0][0x23].raw == 77

    def key(k: str) -> str:
        return request(base + "/keys", {"key": k, "action": "click"})["text"]

    for _ in range(8):
        text = key("mode")
    assert text.strip() == "EASY"
    text = key("set")
    for _ in range(12):
        if text.strip() == "EA00":
            break
        text = key("up")
    assert text.strip() == "EA00"
    assert key("set") == "    0"
    for _ in range(3):
        text = key("up")
    assert text == "    3"
    # Listen before the key: the boot-up may be on the bus before the HTTP answer is back
    # (python-canopen's wait_for_bootup only sees one that comes after it is called).
    booted = threading.Event()
    node.nmt.add_heartbeat_callback(lambda state: state == 0 and booted.set())
    key("set")
    assert booted.wait(5.0), "no boot-up message after EA00 = 3"
    assert node.sdo[0x2FF0][0x23].raw == 30, "the power-on value after the reboot"
