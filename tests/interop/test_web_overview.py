"""The console's overview and parameter table in a real browser (headless Debian Chromium,
Playwright) against `drivetwin run --http`.

The overview: each drive's position follows a profile-position move started over REST, with
its mode, its sparklines, the bus load and a wire fault in force. The parameter table: the
filters by index, name and group find an object, the differs-from-default mark appears after a
write from the page, the DCF export reads back in python-canopen with the drive's values, and
an import of it restores them; an import with a refused value names it and writes nothing.

Screenshots go to docs/console-overview.png and docs/console-parameters.png when
DRIVETWIN_SCREENSHOTS=1.
"""

from __future__ import annotations

import json
import os
import urllib.request

import canopen

from conftest import wait_until
from test_web_console import browser, console_url  # noqa: F401  (the fixture is used by name)
from test_web_pages import DOCS


def call(url: str, method: str = "GET", body: dict | None = None):
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(url, data=data, method=method,
                                 headers={"content-type": "application/json"})
    with urllib.request.urlopen(req, timeout=5) as r:
        return json.loads(r.read())


def shot(page, name: str) -> None:
    if os.environ.get("DRIVETWIN_SCREENSHOTS") == "1":
        page.set_viewport_size({"width": 1400, "height": 900})
        page.screenshot(path=str(DOCS / name), full_page=False)


def page_position(page, drive: int) -> float | None:
    text = page.text_content(f"#cell-table tr[data-drive='{drive}'] td.position .num")
    if not text or text.startswith("–"):
        return None
    return float(text.split()[0])


def test_the_overview_follows_a_move_and_shows_bus_load_and_wire_faults(launch, browser, tmp_path):  # noqa: F811
    cell = tmp_path / "cell.toml"
    # One bus at 125 kbit/s: the CMMP-AS's DIP6/DIP7 OFF, the Kinco's 2F81h = 12.
    cell.write_text('[[drive]]\ndevice = "cmmp-as"\nnode = 1\n\n[[drive]]\ndevice = "kinco-fd3"\nnode = 2\n'
                    '[drive.objects]\n"2F81:00" = 12\n')
    twin = launch(config=cell, extra=("--http", "127.0.0.1:0"))
    url = console_url(twin)
    page = browser.new_page()
    page.set_viewport_size({"width": 1400, "height": 900})
    page.goto(url)

    # Both drives with their state, and live positions from their samples.
    page.wait_for_selector("#cell-table tr[data-drive='1'] td.state")
    wait_until(lambda: page_position(page, 0) is not None and page_position(page, 1) is not None, 5.0,
               what="live positions on the overview")
    assert page.text_content("#cell-table tr[data-drive='0'] td.state") == "SWITCH ON DISABLED"
    assert "load" in page.text_content("#bus-load .bus[data-bus='0']")
    page.wait_for_selector("#wire-faults li.muted")
    assert page.text_content("#wire-faults") == "none"

    # A wire fault in force: a drop of half of node 2's frames.
    fault = call(url + "api/wire/bus/0/faults", "POST", {"fault": "drop", "node": 2, "share": 0.5})
    page.wait_for_selector(f"#wire-faults li[data-front='bus/0'][data-fault='{fault['id']}']")
    assert "drop 50 % on node 2" in page.text_content("#wire-faults"), page.text_content("#wire-faults")

    # The move, over REST: enable, then 20000 increments forwards in profile position mode.
    call(url + "api/drives/0/motion/enable", "POST")
    page.wait_for_function(
        "document.querySelector(\"#cell-table tr[data-drive='0'] td.state\").textContent === 'OPERATION ENABLED'")
    before = call(url + "api/drives/0/plant")["position"]
    call(url + "api/drives/0/motion/move", "POST", {"target": 20000, "relative": True})
    target = before + 20000

    # The page's position settles on the target, and the samples its row was drawn from pass
    # through the move (positions between start and target); the mode is profile position.
    wait_until(lambda: (p := page_position(page, 0)) is not None and abs(p - target) <= 10, 10.0,
               what="the overview's position at the move's target")
    seen = page.evaluate("window.overview.samples.get(0).map((s) => s.position)")
    assert any(before + 100 < p < target - 100 for p in seen), ("no position between start and target", seen)
    assert page.text_content("#cell-table tr[data-drive='0'] td.mode") == "PP (1)"
    # The sparkline of the position has its points, rising to the right.
    points = page.get_attribute("#cell-table tr[data-drive='0'] td.position svg polyline", "points")
    ys = [float(xy.split(",")[1]) for xy in points.split()]
    assert len(ys) > 20 and ys[-1] < ys[0], points
    # The velocity's sparkline has the move's bump: from rest, up to its peak, back.
    points = page.get_attribute("#cell-table tr[data-drive='0'] td.velocity svg polyline", "points")
    ys = [float(xy.split(",")[1]) for xy in points.split()]
    assert len(ys) > 20 and min(ys) < ys[0] - 10 and min(ys) < ys[-1] - 10, points
    page.wait_for_timeout(300)
    shot(page, "console-overview.png")


def test_the_parameter_table_filters_marks_exports_and_imports(launch, node_of, browser, tmp_path):  # noqa: F811
    twin = launch("cmmp-as", 1, extra=("--http", "127.0.0.1:0"))
    url = console_url(twin)
    node = node_of(twin)
    page = browser.new_page()
    page.set_viewport_size({"width": 1400, "height": 900})
    page.goto(url + "#drive/0")
    row = page.locator("#params tr[data-key='6083:00']")
    row.wait_for()

    def shown(key: str) -> bool:
        return page.evaluate(f"!document.querySelector(\"#params tr[data-key='{key}']\").hidden")

    # By index, by name, by group.
    page.fill("#filter-index", "6083")
    assert shown("6083:00") and not shown("6084:00") and not shown("1018:01")
    page.fill("#filter-index", "")
    page.fill("#filter", "profile_acc")
    assert shown("6083:00") and not shown("6081:00")
    page.fill("#filter", "")
    page.select_option("#filter-group", "communication")
    assert shown("1018:01") and not shown("6083:00")
    page.select_option("#filter-group", "")
    assert row.locator("td.default").text_content() == "10000"
    # Units and ranges from the device file: 6083h in accel units; 2073h in µs, 1000 … 50000.
    assert row.locator("td").nth(6).text_content() == "accel units"
    cells = page.locator("#params tr[data-key='2073:00'] td")
    assert [cells.nth(i).text_content() for i in (6, 7, 8, 9)] == ["us", "1000", "50000", "20000"]

    # The differs-from-default mark appears after a write from the page.
    assert row.get_attribute("data-differs") == "0"
    row.locator("input.edit").fill("12345")
    row.locator("button.write").click()
    page.wait_for_function("document.querySelector(\"#params tr[data-key='6083:00']\").dataset.differs === '1'")
    assert row.locator("td.differs").text_content() == "≠"
    assert node.sdo[0x6083].raw == 12345
    page.check("#filter-differs")
    assert shown("6083:00") and not shown("6084:00")
    page.uncheck("#filter-differs")
    page.fill("#filter-index", "608")
    if os.environ.get("DRIVETWIN_SCREENSHOTS") == "1":
        page.locator("#params-panel").screenshot(path=str(DOCS / "console-parameters.png"))
    page.fill("#filter-index", "")

    # Export: a DCF python-canopen reads, with the drive's values and node.
    with page.expect_download() as dl:
        page.click("#params-export")
    dcf = tmp_path / "drive.dcf"
    dl.value.save_as(dcf)
    text = dcf.read_text()
    assert "[DeviceComissioning]" in text and "NodeID=0x1" in text
    od = canopen.import_od(str(dcf), node_id=1)
    assert od[0x6083].value == 12345 and od[0x6083].default == 10000
    assert od[0x6084].value == node.sdo[0x6084].raw

    # Another value over SDO, then the import: the exported value is back.
    node.sdo[0x6083].raw = 5000
    page.set_input_files("#params-import", str(dcf))
    page.wait_for_function("document.querySelector('#params-message').textContent.startsWith('imported')")
    message = page.text_content("#params-message")
    assert "6083:00" in message and "written" in message, message
    assert node.sdo[0x6083].raw == 12345

    # A file with a value above its maximum (2073h: 1000 … 50000 µs) and a good one: the
    # refused value is named with its reason, and the good one is not written either.
    node.sdo[0x6083].raw = 5000
    bad = tmp_path / "bad.dcf"
    bad.write_text(with_value(text, "2073", "60000"))
    page.set_input_files("#params-import", str(bad))
    page.wait_for_selector("#params-message li[data-refused='2073:00']")
    refusal = page.text_content("#params-message")
    assert "nothing was written" in refusal and "above the maximum 50000" in refusal, refusal
    assert node.sdo[0x6083].raw == 5000, "nothing half-applied"


def with_value(text: str, section: str, value: str) -> str:
    """`text` with section `section`'s ParameterValue set to `value`."""
    head = f"[{section}]\n"
    start = text.index(head)
    end = text.index("\n\n", start)
    lines = [line for line in text[start:end].split("\n") if not line.startswith("ParameterValue=")]
    return text[:start] + "\n".join([*lines, f"ParameterValue={value}"]) + text[end:]
