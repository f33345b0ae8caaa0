"""The web console in a real browser: headless Debian Chromium driven by Playwright against
`drivetwin run --http`. A parameter written in the page is read back over SDO with
python-canopen; a drive enabled from the page moves, and the scope's trace moves with it.

The browser tests skip cleanly where Chromium (/usr/bin/chromium) or Playwright is not
installed, the schemathesis run where schemathesis is not.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile

import pytest

from conftest import free_port, wait_until
from scope_page import assert_the_scope_moves

CHROMIUM = os.environ.get("DRIVETWIN_CHROMIUM", "/usr/bin/chromium")

# The machine's network is closed: Chromium's own background connections are switched off.
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]


@pytest.fixture
def browser():
    if shutil.which(CHROMIUM) is None:
        pytest.skip(f"no Chromium at {CHROMIUM} (apt-get install chromium)")
    sync_api = pytest.importorskip("playwright.sync_api")
    with tempfile.TemporaryDirectory() as profile, sync_api.sync_playwright() as pw:
        context = pw.chromium.launch_persistent_context(
            profile, executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        try:
            yield context
        finally:
            context.close()


def console_url(twin) -> str:
    line = wait_until(lambda: next((l for l in twin.stdout_lines if l.startswith("web console on ")), None),
                      5.0, what="the 'web console on' line")
    m = re.match(r"web console on (http://127\.0\.0\.1:\d+/)$", line)
    assert m, line
    return m.group(1)


def test_parameter_written_in_the_page_reads_back_over_sdo_and_the_scope_moves(
        launch, node_of, browser, tmp_path):
    twin = launch("cmmp-as", 1, extra=("--http", "127.0.0.1:0"))
    url = console_url(twin)
    node = node_of(twin)
    page = browser.new_page()
    page.goto(url + "#drive/0")
    page.wait_for_selector("#drives a[data-drive='0']")
    assert "SWITCH ON DISABLED" in page.text_content("#state")

    # 60FFh target velocity, typed into the parameter table and written from the page. Slow
    # enough that the axis stays clear of its limit switch for the test's few seconds (at
    # 1500 rpm it reaches it in about 2 s and the drive faults).
    row = page.locator("#params tr[data-key='60FF:00']")
    row.wait_for()
    row.locator("input.edit").fill("300")
    row.locator("button.write").click()
    page.wait_for_function(
        "document.querySelector(\"#params tr[data-key='60FF:00'] td.value\").textContent === '300'")
    assert node.sdo[0x60FF].raw == 300, "the page's write is the drive's value on the bus"

    # Profile velocity mode over SDO, then Enable in the page: the motor turns.
    node.sdo[0x6060].raw = 3
    page.click("#enable")
    page.wait_for_function("document.querySelector('#state').textContent === 'OPERATION ENABLED'",
                           timeout=5000)
    assert node.sdo[0x6041].raw & 0x6F == 0x27

    # The scope's samples and its drawing move.
    assert_the_scope_moves(page)
    page.screenshot(path=str(tmp_path / "console.png"), full_page=True)

    page.click("#disable")
    try:
        page.wait_for_function(
            "document.querySelector('#state').textContent === 'READY TO SWITCH ON'", timeout=5000)
    except Exception:
        pytest.fail(f"state {page.text_content('#state')!r}, message {page.text_content('#message')!r}, "
                    f"6041h {node.sdo[0x6041].raw:#06x}")


# Counts the frames the page asks for, and records every change of the page outside the
# scope's plot (a MutationObserver), from `window.watchPage()` on.
WATCH_PAGE = """
(() => {
  const raf = window.requestAnimationFrame.bind(window);
  window.framesAsked = 0;
  window.requestAnimationFrame = (f) => { window.framesAsked += 1; return raf(f); };
  window.watchPage = () => {
    window.framesAsked = 0;
    window.pageChanges = [];
    const where = (n) => {
      const e = n.nodeType === 1 ? n : n.parentElement;
      return e ? (e.id ? `#${e.id}` : `${e.tagName.toLowerCase()}.${e.className.baseVal ?? e.className}`
                  + (e.closest("[id]") ? ` in #${e.closest("[id]").id}` : "")) : "?";
    };
    if (window.pageWatch) window.pageWatch.disconnect();
    window.pageWatch = new MutationObserver((ms) => {
      for (const m of ms) {
        const n = m.target.nodeType === 1 ? m.target : m.target.parentElement;
        if (n && n.closest("#scope-plot")) continue;
        window.pageChanges.push(`${m.type} ${m.attributeName ?? ""} ${where(m.target)}`);
      }
    }).observe(document.body, { subtree: true, childList: true, characterData: true, attributes: true });
  };
})();
"""


def test_a_page_at_rest_writes_nothing_and_asks_for_no_frame(launch, browser):
    """A drive at rest answers the same view every second: its page writes no text and
    rebuilds no table (each write makes the browser lay out and paint the page again), and with
    the scope paused it asks for no animation frame at all. The cell page's rows and texts
    stay as they are too (only a sparkline still filling its window is drawn)."""
    twin = launch("cmmp-as", 1, extra=("--http", "127.0.0.1:0"))
    page = browser.new_page()
    page.add_init_script(WATCH_PAGE)

    # The cell page: rows built once, texts written only when they change.
    page.goto(console_url(twin))
    page.wait_for_function("/inc$/.test(document.querySelector(\"#cell-table tr[data-drive='0'] td.position .num\")"
                           "?.textContent ?? '')")
    page.wait_for_selector("#wire-faults li")
    page.wait_for_timeout(1200)
    page.evaluate("window.watchPage()")
    page.wait_for_timeout(3200)
    changes = [c for c in page.evaluate("window.pageChanges") if c != "attributes points polyline. in #cell-table"]
    assert changes == [], changes

    # The drive's page.
    page.goto(console_url(twin) + "#drive/0")
    page.wait_for_selector("#status-bits tr[data-bit='6041h.6']")
    page.wait_for_selector("#params tr[data-key='6083:00']")
    page.wait_for_function("window.consoleState.samples.length > 20")
    assert page.text_content("#state") == "SWITCH ON DISABLED"

    # Live scope: nothing outside the plot changes over three refreshes of the page.
    page.wait_for_timeout(500)
    page.evaluate("window.watchPage()")
    page.wait_for_timeout(3200)
    assert page.evaluate("window.pageChanges") == []
    assert page.evaluate("window.framesAsked") > 0, "the live scope draws its samples"

    # Paused: no frame asked for, nothing written.
    page.click("#pause")
    page.wait_for_timeout(500)
    page.evaluate("window.watchPage()")
    page.wait_for_timeout(3200)
    assert page.evaluate("window.pageChanges") == []
    assert page.evaluate("window.framesAsked") == 0

    # A change is still shown: Enable, and the state and its bits are drawn.
    page.click("#enable")
    page.wait_for_function("document.querySelector('#state').textContent === 'OPERATION ENABLED'")
    assert "bit-on" in (page.get_attribute("#status-bits tr[data-bit='6041h.2']", "class") or "")


def test_a_refused_write_shows_the_sdo_abort_text(launch, browser):
    twin = launch("cmmp-as", 1, extra=("--http", "127.0.0.1:0"))
    page = browser.new_page()
    page.goto(console_url(twin) + "#drive/0")
    # 6060h modes of operation: 99 is no mode of the CMMP-AS (§6.2), the drive aborts.
    row = page.locator("#params tr[data-key='6060:00']")
    row.wait_for()
    row.locator("input.edit").fill("99")
    row.locator("button.write").click()
    page.wait_for_function("document.querySelector('#message').className === 'error'")
    message = page.text_content("#message")
    assert "SDO abort 0x06090030: Invalid value for parameter" in message, message
    # Text where a number is due is refused before it reaches the drive.
    row.locator("input.edit").fill("fast")
    row.locator("button.write").click()
    page.wait_for_function("document.querySelector('#message').textContent.includes('not a number')")


def test_enable_on_a_factory_kinco_shows_din1_and_the_rule_next_to_the_button(
        launch, node_of, browser):
    """A factory Kinco FD3: DIN1 has the function Enable and owns the controlword (manual
    §5.5, L1287). Enable clicked in the page is refused, and the page says why beside the
    button: DIN1, Din1_Function 2010h:03, the manual's rule. With Din1_Function = 0 written
    over SDO, as a bus master does, the same click enables the drive and the reason goes."""
    twin = launch("kinco-fd3", 1, extra=("--http", "127.0.0.1:0"))
    node = node_of(twin)
    page = browser.new_page()
    page.goto(console_url(twin) + "#drive/0")
    page.wait_for_selector("#drives a[data-drive='0']")
    page.wait_for_function("document.querySelector('#state').textContent === 'READY TO SWITCH ON'")
    assert page.is_hidden("#enable-why")

    page.click("#enable")
    page.wait_for_selector("#enable-why", state="visible", timeout=5000)
    reason = page.text_content("#enable-why .reason")
    rule = page.text_content("#enable-why .rule")
    assert reason.startswith("DIN1 has the function Enable (2010h:03)"), reason
    assert "6040h" in reason, reason
    assert "L1287" in rule and "highest priority" in rule, rule
    assert page.get_attribute("#enable-why", "data-kind") == "input_owns_object"
    assert page.get_attribute("#message", "class") == "error"
    assert node.sdo[0x6041].raw & 0x6F == 0x21, "still READY TO SWITCH ON"

    node.sdo[0x2010][0x03].raw = 0
    page.click("#enable")
    page.wait_for_function("document.querySelector('#state').textContent === 'OPERATION ENABLED'",
                           timeout=5000)
    assert page.is_hidden("#enable-why")
    assert node.sdo[0x6041].raw & 0x6F == 0x27


def test_inputs_forced_in_the_page_show_in_60fd_over_sdo(launch, node_of, browser):
    twin = launch("cmmp-as", 1, extra=("--http", "127.0.0.1:0"))
    node = node_of(twin)
    page = browser.new_page()
    page.goto(console_url(twin) + "#drive/0")
    page.wait_for_selector("#params tr[data-key='60FD:00']")
    before = node.sdo[0x60FD].raw
    # DIN4 (output-stage enable) and DIN5 (controller enable) forced low.
    page.fill("#din-mask", "0x30")
    page.fill("#din-levels", "0")
    page.click("#set-inputs")
    page.wait_for_function("document.querySelector('#message').textContent.startsWith('inputs forced')")
    after = wait_until(lambda: (v := node.sdo[0x60FD].raw) != before and [v], 2.0, what="60FDh to change")
    assert after[0] != before


# Schemathesis's run: its coverage phase (every operation with its boundary and invalid values,
# deterministic), 30 generated cases per operation (fuzzing phase) and the stateful phase. An
# operation that reads or writes a drive's whole dictionary (the CMMO-ST's: about 1 MB, a second
# or more an answer, each entry one request to the cell's loop) has no input but the drive's
# index and the DCF text: 5 generated cases each.
SCHEMATHESIS_CONFIG = """\
generation.max-examples = 30

[[operations]]
include-name = ["GET /api/drives/{drive}/objects", "GET /api/drives/{drive}/parameters",
                "GET /api/drives/{drive}/parameters/dcf", "PUT /api/drives/{drive}/parameters/dcf"]
generation.max-examples = 5
"""


def test_schemathesis_finds_no_server_error_and_every_status_documented(launch, tmp_path):
    """Schemathesis against /api/openapi.json of a cell with a CMMP-AS and a CMMO-ST: no 5xx,
    every status code and content type as documented, every body as its schema says."""
    pytest.importorskip("schemathesis")
    cli = shutil.which("schemathesis") or shutil.which("st")
    if cli is None:
        pytest.skip("the schemathesis command is not on PATH")
    import subprocess
    cell = tmp_path / "cell.toml"
    cell.write_text(
        '[[drive]]\ndevice = "cmmp-as"\nnode = 1\n\n'
        f'[[drive]]\ndevice = "cmmo-st"\nmodbus = "127.0.0.1:{free_port()}"\n')
    twin = launch(config=cell, extra=("--http", "127.0.0.1:0"))
    url = console_url(twin)
    config = tmp_path / "schemathesis.toml"
    config.write_text(SCHEMATHESIS_CONFIG)
    r = subprocess.run(
        [cli, "--config-file", str(config), "run", url + "api/openapi.json", "--checks",
         "not_a_server_error,status_code_conformance,content_type_conformance,"
         "response_schema_conformance",
         "--request-timeout", "10", "--seed", "20261127"],
        capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stdout[-6000:] + r.stderr[-2000:]


def test_beyond_loopback_the_console_prints_a_token_and_writes_need_it(launch):
    """Bound to every address, the console prints a token; a write without it is refused with
    401 and a message, with it the write is done; reads need none."""
    import json
    import urllib.error
    import urllib.request
    twin = launch("cmmp-as", 1, extra=("--http", "0.0.0.0:0"))
    line = wait_until(lambda: next((l for l in twin.stdout_lines if l.startswith("web console on ")), None),
                      5.0, what="the 'web console on' line")
    m = re.match(r"web console on http://0\.0\.0\.0:(\d+)/\?token=([0-9a-f]{32})$", line)
    assert m, line
    base, token = f"http://127.0.0.1:{m.group(1)}", m.group(2)

    def put(headers):
        req = urllib.request.Request(base + "/api/drives/0/objects/6081/0", method="PUT",
                                     data=json.dumps({"value": 1234}).encode(),
                                     headers={"content-type": "application/json", **headers})
        try:
            with urllib.request.urlopen(req, timeout=5) as r:
                return r.status, json.load(r)
        except urllib.error.HTTPError as e:
            return e.code, json.load(e)

    status, body = put({})
    assert status == 401 and "token" in body["error"], (status, body)
    status, body = put({"x-drivetwin-token": "0" * 32})
    assert status == 401, (status, body)
    status, body = put({"x-drivetwin-token": token})
    assert (status, body["value"]) == (200, "1234"), (status, body)
    with urllib.request.urlopen(base + "/api/drives/0/objects/6081/0", timeout=5) as r:
        assert json.load(r)["value"] == "1234"
