"""Diagnostic messages injected through the REST API of `drivetwin run --http`, seen on the bus
by python-canopen: POST /api/drives/0/diagnostics/03-0 makes the CMMP-AS
send EMCY 4310h with the temperature bit (CMMP-EMCY-03), put 4310h in 1003h:01 and go to
FAULT; DELETE and a fault reset acknowledge it with EMCY 0000h (CMMP-EMCY-01)."""

from __future__ import annotations

import json
import re
import urllib.error
import urllib.request

from conftest import wait_until
from test_fhpp_diagnostics import acknowledge
from test_fhpp_modbus import (  # noqa: F401  (cmmo is a fixture)
    CCON_RECORD_ENABLED, CPOS_HALT, SCON_FAULT, cmmo, cycle_until, enable_and_home, telegram)


def console_url(twin) -> str:
    line = wait_until(lambda: next((l for l in twin.stdout_lines if l.startswith("web console on ")), None),
                      5.0, what="the 'web console on' line")
    m = re.match(r"web console on (http://127\.0\.0\.1:\d+/)$", line)
    assert m, line
    return m.group(1)


def call(url: str, method: str = "GET"):
    req = urllib.request.Request(url, method=method)
    try:
        with urllib.request.urlopen(req, timeout=5) as r:
            return r.status, json.load(r)
    except urllib.error.HTTPError as e:
        return e.code, json.load(e)


def test_message_raised_over_rest_is_an_emcy_and_a_1003h_entry(launch, node_of):
    twin = launch("cmmp-as", 1, extra=("--http", "127.0.0.1:0"))
    url = console_url(twin)
    node = node_of(twin)
    status, table = call(url + "api/drives/0/diagnostics")
    assert status == 200 and len(table) >= 230, (status, len(table))
    row = next(r for r in table if r["number"] == "03-0")
    assert (row["code"], row["active"]) == ("0x4310", False), row

    status, row = call(url + "api/drives/0/diagnostics/03-0", "POST")
    assert status == 200 and row["active"], row
    wait_until(lambda: any(e.code == 0x4310 for e in node.emcy.log), 2.0, what="EMCY 4310h")
    emcy = next(e for e in node.emcy.log if e.code == 0x4310)
    assert emcy.register == 0x09, "generic + temperature (Tab. 3.9)"
    assert node.sdo[0x1003][1].raw & 0xFFFF == 0x4310, "1003h:01 newest entry"
    wait_until(lambda: node.sdo[0x6041].raw & 0x4F == 0x08, 2.0, what="FAULT")

    # The cause stays until cleared: a fault reset now changes nothing.
    node.sdo[0x6040].raw = 0x00
    node.sdo[0x6040].raw = 0x80
    assert node.sdo[0x6041].raw & 0x4F == 0x08
    status, row = call(url + "api/drives/0/diagnostics/03-0", "DELETE")
    assert status == 200, row
    node.sdo[0x6040].raw = 0x00
    node.sdo[0x6040].raw = 0x80
    wait_until(lambda: node.emcy.log[-1].code == 0x0000, 3.0,
               what=f"EMCY 0000h: {[hex(e.code) for e in node.emcy.log]}, "
                    f"6041h {node.sdo[0x6041].raw:#06x}")
    assert node.sdo[0x6041].raw & 0x4F == 0x40, "SWITCH ON DISABLED"

    status, err = call(url + "api/drives/0/diagnostics/99-9", "POST")
    assert status == 404 and "error" in err, (status, err)


def test_cmmo_st_message_raised_over_rest_shows_in_fhpp_and_fc_07(cmmo):
    """App. D 2Fh following error raised through the REST API: SCON.FAULT in the cyclic
    telegram and FC 07h Read Exception Status = 2Fh (FHPP-MB-05); cleared through the API,
    CCON.RESET acknowledges it."""
    twin = cmmo("--http", "127.0.0.1:0")
    line = wait_until(lambda: next((l for l in twin.lines if l.startswith("web console on ")), None),
                      5.0, what="the 'web console on' line")
    url = line.removeprefix("web console on ")
    c = twin.client()
    try:
        enable_and_home(c)
        status, row = call(url + "api/drives/0/diagnostics/2Fh", "POST")
        assert status == 200 and row["active"], row
        cycle_until(c, telegram(CCON_RECORD_ENABLED, CPOS_HALT),
                    lambda s: s["scon"] & SCON_FAULT, timeout=3, what="SCON.FAULT")
        assert c.read_exception_status().status == 0x2F
        status, row = call(url + "api/drives/0/diagnostics/2Fh", "DELETE")
        assert status == 200, row
        acknowledge(c)
        assert c.read_exception_status().status == 0
    finally:
        c.close()
