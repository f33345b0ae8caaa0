"""The console's pages in a real browser (headless Debian Chromium, Playwright) against
`drivetwin run --http`: the drive page's motion buttons move the drive and the scope's trace;
a limit switch forced on a digital input faults the drive and the page and the cell page show
the fault with its text; the CMMO-ST's own web server with its four tabs, Device Control
before saving and the settings that need a restart. `drivetwin iodd` writes the two IODD 1.1
files of the CMMO-ST manual.

Screenshots of the pages go to docs/ when DRIVETWIN_SCREENSHOTS=1 (small PNGs).
"""

from __future__ import annotations

import os
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from conftest import REPO_ROOT, free_port, run_cli, wait_until
from scope_page import arm_trigger, assert_the_scope_moves
from test_web_console import browser, console_url  # noqa: F401  (the fixture is used by name)

DOCS = REPO_ROOT / "docs"


def screenshot(page, name: str) -> None:
    if os.environ.get("DRIVETWIN_SCREENSHOTS") == "1":
        page.set_viewport_size({"width": 1280, "height": 900})
        page.screenshot(path=str(DOCS / name), full_page=False)


def test_enable_and_jog_in_the_page_move_the_scope_trace(launch, node_of, browser):  # noqa: F811
    twin = launch("cmmp-as", 1, extra=("--http", "127.0.0.1:0"))
    node = node_of(twin)
    page = browser.new_page()
    page.goto(console_url(twin) + "#drive/0")
    page.wait_for_selector("#status-bits tr[data-bit='6041h.6']")
    assert page.text_content("#state") == "SWITCH ON DISABLED"
    page.click("#enable")
    page.wait_for_function("document.querySelector('#state').textContent === 'OPERATION ENABLED'")
    assert node.sdo[0x6041].raw & 0x6F == 0x27
    # Bit 2 "operation enabled" is shown set.
    assert "bit-on" in (page.get_attribute("#status-bits tr[data-bit='6041h.2']", "class") or "")

    # Hold Jog +: profile velocity at the page's speed.
    page.fill("#jog-speed", "300")
    page.dispatch_event("#jog-pos", "pointerdown")
    page.wait_for_function("document.querySelector('#message').textContent === 'jogging +'")
    assert node.sdo[0x6060].raw == 3 and node.sdo[0x60FF].raw == 300
    assert_the_scope_moves(page)
    # 60F4h following error is sampled with every plant sample, on the cell loop.
    page.wait_for_function(
        "window.consoleState.samples.filter((p) => p.following_error != null).length > 50")
    assert page.evaluate("window.consoleState.samples.slice(-20).every((p) => p.following_error != null)")
    page.wait_for_timeout(1500)
    screenshot(page, "console-drive.png")
    # Any object beside them: 6041h, sampled and plotted as "object".
    page.fill("#scope-object", "6041:0")
    page.click("#scope-object-set")
    page.wait_for_function(
        "window.consoleState.samples.filter((p) => p.object != null).length > 20")
    assert page.evaluate("window.consoleState.samples.at(-1).object") & 0x6F == 0x27
    assert page.text_content("#connection") == ""

    # Release: the jog stops (60FFh = 0) and the motor comes to rest.
    page.dispatch_event("#jog-pos", "pointerup")
    page.wait_for_function("document.querySelector('#message').textContent === 'jog stopped'")
    assert node.sdo[0x60FF].raw == 0
    page.wait_for_function(
        "Math.abs(window.consoleState.samples.at(-1).velocity) < 5", timeout=5000)

    # Move to: profile position with the set-point handshake, relative 2000 increments.
    page.fill("#move-target", "2000")
    page.check("#move-relative")
    page.click("#move")
    page.wait_for_function("document.querySelector('#message').textContent.startsWith('moving to')")
    assert node.sdo[0x6060].raw == 1 and node.sdo[0x607A].raw == 2000


def test_a_trigger_captures_the_window_around_the_crossing(launch, browser):  # noqa: F811
    twin = launch("cmmp-as", 1, extra=("--http", "127.0.0.1:0"))
    page = browser.new_page()
    page.goto(console_url(twin) + "#drive/0")
    page.wait_for_selector("#status-bits tr[data-bit='6041h.6']")
    # Velocity rising through 150, 25 % pre-trigger, a 2 s window, single shot.
    arm_trigger(page, "velocity", 150, 25, 2)
    page.click("#enable")
    page.wait_for_function("document.querySelector('#state').textContent === 'OPERATION ENABLED'")
    page.dispatch_event("#jog-pos", "pointerdown")
    page.wait_for_function("window.consoleState.triggers === 1", timeout=8000)
    page.dispatch_event("#jog-pos", "pointerup")
    cap = page.evaluate("(() => { const c = window.consoleState.capture;"
                        " return {t0: c.t0, t1: c.t1, at: c.at, n: c.samples.length,"
                        " before: c.samples.filter((p) => p.t < c.at).map((p) => p.velocity)}; })()")
    assert abs((cap["at"] - cap["t0"]) - 0.5) < 1e-6, cap  # 25 % of 2 s before the crossing
    assert abs((cap["t1"] - cap["t0"]) - 2.0) < 1e-6, cap
    assert cap["before"] and max(cap["before"]) < 150, "before the crossing the velocity is below the level"
    assert page.evaluate("window.consoleState.paused"), "single shot pauses the scope"


def test_a_forced_limit_switch_shows_the_fault_and_its_text(launch, browser):  # noqa: F811
    twin = launch("cmmp-as", 1, extra=("--http", "127.0.0.1:0"))
    url = console_url(twin)
    page = browser.new_page()
    page.goto(url + "#drive/0")
    page.wait_for_selector("#status-bits tr[data-bit='6041h.6']")
    page.click("#enable")
    page.wait_for_function("document.querySelector('#state').textContent === 'OPERATION ENABLED'")
    page.dispatch_event("#jog-pos", "pointerdown")
    page.wait_for_function("document.querySelector('#message').textContent === 'jogging +'")
    # DIN7: limit switch E1, positive (6510h:12 = 0), normally open (6510h:11 = 1).
    page.fill("#din-mask", "0x80")
    page.fill("#din-levels", "0x80")
    page.click("#set-inputs")
    page.wait_for_function("document.querySelector('#state').textContent === 'FAULT'", timeout=5000)
    page.wait_for_function(
        "document.querySelector('#active-error').textContent.includes('8082h Limit switch: positive setpoint blocked')")
    page.wait_for_function(
        "[...document.querySelectorAll('#history td')].some((td) => td.textContent.startsWith('Limit switch'))")
    page.dispatch_event("#jog-pos", "pointerup")
    page.wait_for_function("document.querySelector('#message').textContent === 'jog stopped'")
    screenshot(page, "console-fault.png")
    # The cell page: the drive's state and its error with the text.
    page.goto(url + "#")
    page.wait_for_function(
        "(document.querySelector(\"#cell-table tr[data-drive='0'] td.error\") || {}).textContent"
        " === '8082h Limit switch: positive setpoint blocked (message 43-1)'")
    assert "FAULT" in page.text_content("#cell-table tr[data-drive='0'] td.state")
    screenshot(page, "console-cell.png")


def cmmo_st_cell(tmp_path: Path) -> Path:
    cell = tmp_path / "cell.toml"
    # A CMMP-AS too: the launcher waits for the CAN side. The CMMO-ST is drive 1 (the CAN
    # drives come first).
    cell.write_text('[[drive]]\ndevice = "cmmp-as"\nnode = 1\n\n'
                    f'[[drive]]\ndevice = "cmmo-st"\nmodbus = "127.0.0.1:{free_port()}"\n')
    return cell


def test_the_cmmo_st_web_server_has_four_tabs_and_saves_only_with_device_control(
        launch, browser, tmp_path):  # noqa: F811
    twin = launch(config=cmmo_st_cell(tmp_path), extra=("--http", "127.0.0.1:0"))
    url = console_url(twin)
    page = browser.new_page()
    # The console's drive page links the device's own web server.
    page.goto(url + "#drive/1")
    page.wait_for_selector("#status-bits tr[data-bit='SCON.4']")
    assert not page.is_hidden("#web-server-link")
    page.click("#web-server")
    page.wait_for_url("**/cmmo-st/1")
    page.wait_for_function("window.webServer.view !== null")
    tabs = page.eval_on_selector_all("[role=tab]", "ts => ts.map((t) => t.textContent)")
    assert tabs == ["Control Interface", "FHPP Profile", "Network", "Info"]
    assert page.input_value("#control_interface") == "MODBUS"
    assert page.input_value("#tcp_port") == "502"
    # Settings needing a restart are marked.
    assert page.locator("#p-interface [data-restart]").count() == 3
    page.click("#tab-info")
    assert page.text_content("#i-product") == "CMMO-ST-C5-1-LKP"
    assert page.text_content("#i-firmware").startswith("V1.5")
    page.click("#tab-profile")
    page.check("input[name=device_profile][value='FHPP + FPC Channel']")
    # Without Device Control, saving is refused.
    assert not page.is_checked("#device-control")
    page.click("#save")
    page.wait_for_function("document.querySelector('#message').className === 'error'")
    assert "activate Device Control before saving" in page.text_content("#message")
    # With it, saved; the profile takes effect after a restart.
    page.check("#device-control")
    page.wait_for_function("document.querySelector('#message').textContent === 'Device Control active'")
    assert page.text_content("#control-held") == "device control: web server"
    page.click("#save")
    page.wait_for_function("document.querySelector('#message').textContent.startsWith('saved; restart')")
    assert "after restart" in page.text_content("[data-pending='device_profile']")
    screenshot(page, "cmmo-st-web-server.png")
    page.click("#restart")
    page.wait_for_function("document.querySelector('#message').textContent === 'controller restarted'")
    assert page.text_content("[data-pending='device_profile']") == ""
    assert page.is_checked("input[name=device_profile][value='FHPP + FPC Channel']")
    assert not page.is_checked("#device-control"), "after a restart the fieldbus has control (PNU 125)"


def test_cmmo_st_enable_from_the_console_refused_while_the_web_server_has_control(
        launch, browser, tmp_path):  # noqa: F811
    import json
    import urllib.error
    import urllib.request
    twin = launch(config=cmmo_st_cell(tmp_path), extra=("--http", "127.0.0.1:0"))
    base = console_url(twin).rstrip("/")

    def post(path, body=None):
        req = urllib.request.Request(base + path, method="POST",
                                     data=json.dumps(body).encode() if body is not None else None,
                                     headers={"content-type": "application/json"})
        try:
            with urllib.request.urlopen(req, timeout=10) as r:
                return r.status, json.load(r)
        except urllib.error.HTTPError as e:
            return e.code, json.load(e)

    status, view = post("/api/cmmo-st/1/device-control", {"active": True})
    assert status == 200 and view["device_control"], view
    status, body = post("/api/drives/1/motion/enable")
    assert status == 409 and "Device Control" in body["error"], body
    status, view = post("/api/cmmo-st/1/device-control", {"active": False})
    assert status == 200 and not view["device_control"]
    # Given back, the console's FHPP telegram is the drive's again.
    status, view = post("/api/drives/1/motion/enable")
    assert status == 200 and view["state"].startswith("OPERATION ENABLED"), view
    assert view["device_control"] == "fieldbus"
    # Jog + (CPOS.JOGP) and back; homing (CPOS.HOM) then a direct-mode move.
    status, view = post("/api/drives/1/motion/jog", {"direction": 1})
    assert status == 200, view
    status, view = post("/api/drives/1/motion/jog", {"direction": 0})
    assert status == 200, view
    status, view = post("/api/drives/1/motion/home")
    assert status == 200, view
    wait_until(lambda: post("/api/drives/1/motion/move", {"target": 1000})[0] == 200, 10.0,
               interval=0.5, what="a direct-mode move once homed")
    status, view = post("/api/drives/1/motion/disable")
    assert status == 200 and view["state"].startswith("DISABLED"), view


def test_iodd_writes_the_two_files_of_the_manual(tmp_path):
    r = run_cli("iodd", "--device", "cmmo-st", "--output-dir", str(tmp_path))
    assert r.returncode == 0, r.stderr
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["Festo-CMMO-ST-C5-1-LKP_FHPP-20170501-IODD1.1.xml",
                     "Festo-CMMO-ST-C5-1-LKP_FHPP_and_FPC-20170501-IODD1.1.xml"], names
    ns = {"i": "http://www.io-link.com/IODD/2010/10"}
    for name, octets in zip(names, (8, 16)):
        root = ET.parse(tmp_path / name).getroot()
        assert root.tag == "{http://www.io-link.com/IODD/2010/10}IODevice"
        for path in ("i:DocumentInfo", "i:ProfileHeader", "i:ProfileBody/i:DeviceIdentity",
                     "i:ProfileBody/i:DeviceFunction/i:VariableCollection",
                     "i:ProfileBody/i:DeviceFunction/i:ProcessDataCollection",
                     "i:ProfileBody/i:DeviceFunction/i:UserInterface",
                     "i:CommNetworkProfile", "i:ExternalTextCollection", "i:Stamp"):
            assert root.find(path, ns) is not None, (name, path)
        pd_in = root.find(".//i:ProcessDataIn", ns)
        assert pd_in.get("bitLength") == str(octets * 8), name
        texts = {t.get("id") for t in root.iter("{http://www.io-link.com/IODD/2010/10}Text")}
        for el in root.iter():
            if el.get("textId"):
                assert el.get("textId") in texts, (name, el.get("textId"))
        if shutil.which("xmllint"):
            import subprocess
            assert subprocess.run(["xmllint", "--noout", str(tmp_path / name)]).returncode == 0
    bad = run_cli("iodd", "--device", "cmmp-as", "--output-dir", str(tmp_path))
    assert bad.returncode != 0 and "IO-Link" in bad.stderr


def test_the_kinco_panel_on_the_drive_page_walks_its_menus(launch, node_of, browser):  # noqa: F811
    """The Kinco panel in the page: the Kinco FD3's five digits and its four keys. MODE three
    times and SET open F003's first parameter; the digits follow each key; a CMMP-AS page
    has no panel."""
    twin = launch("kinco-fd3", 1, extra=("--http", "127.0.0.1:0"))
    page = browser.new_page()
    page.goto(console_url(twin) + "#drive/0")
    page.wait_for_selector("#kinco-panel:not([hidden])")
    page.wait_for_function("document.querySelector('#panel-digits').textContent === '    0'")

    def click(key: str):
        sel = f".panel-key[data-key='{key}']"
        page.dispatch_event(sel, "pointerdown")
        page.dispatch_event(sel, "pointerup")

    shown = []
    for _ in range(3):
        click("mode")
        page.wait_for_function(
            f"document.querySelector('#panel-digits').textContent.trim() === 'F00{len(shown) + 1}'")
        shown.append(page.text_content("#panel-digits").strip())
    assert shown == ["F001", "F002", "F003"]
    click("set")
    page.wait_for_function("/^ d3\\.\\d\\d$/.test(document.querySelector('#panel-digits').textContent)")
    # The page shows what the drive shows (the REST view of the same panel).
    import json
    import urllib.request

    with urllib.request.urlopen(console_url(twin) + "api/drives/0/panel", timeout=5) as r:
        assert json.loads(r.read())["text"] == page.text_content("#panel-digits")
    if os.environ.get("DRIVETWIN_SCREENSHOTS") == "1":
        page.set_viewport_size({"width": 1280, "height": 900})
        page.locator("#kinco-panel").scroll_into_view_if_needed()
        page.screenshot(path=str(DOCS / "console-kinco-panel.png"), full_page=False)
    page.close()

    other = launch("cmmp-as", 2, extra=("--http", "127.0.0.1:0"))
    page = browser.new_page()
    page.goto(console_url(other) + "#drive/0")
    page.wait_for_function("document.querySelector('#state').textContent.length > 0")
    assert page.is_hidden("#kinco-panel")
