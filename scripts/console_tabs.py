#!/usr/bin/env python3
"""Does a browser on the console cost the cell loop? The loop's timer lateness of
`drivetwin run` without a browser and with 5 Chromium tabs open on the scope, side by side in
one run: the two runs alternate for `--rounds` pairs (the machine may be shared; a pair sees
the same load), each for `--seconds`, and each prints the figures the binary prints when it
stops ("cell loop: N timers served, late p50 ≤ …, p99 ≤ …, p99.9 ≤ …, max …").

The cell: 8 CMMP-AS on one CAN bus at 125 kbit/s, drive 0 enabled and moving back and forth
(profile position, ±20000 increments) so that its plant and the scope's traces change. Each
tab opens drive 0's page (its scope of position, velocity, current and 60F4h, its parameter
table, its state polled each second) with the scope at 1 kHz; the page loads count too, as
the lateness histogram covers the whole run.

    DRIVETWIN_BIN=target/release/drivetwin python3 scripts/console_tabs.py [--rounds 3]
        [--seconds 15] [--tabs 5] [--rt-priority 80]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from pathlib import Path

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"]
DRIVES = 8


def call(url: str, method: str = "GET", body: dict | None = None):
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(url, data=data, method=method, headers={"content-type": "application/json"})
    with urllib.request.urlopen(req, timeout=5) as r:
        return json.loads(r.read())


def free_port() -> int:
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Twin:
    def __init__(self, binary: str, cell: Path, rt: int | None):
        args = [binary, "run", "--config", str(cell), "--http", "127.0.0.1:0",
                "--socketcand", f"127.0.0.1:{free_port()}", "--channel", "vcan0"]
        if rt:
            args += ["--rt-priority", str(rt)]
        self.proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, bufsize=1)
        self.lines: list[str] = []
        self.url: str | None = None
        ready = threading.Event()

        def read():
            for line in self.proc.stdout:
                self.lines.append(line.rstrip("\n"))
                m = re.match(r"web console on (http://\S+/)$", line.strip())
                if m:
                    self.url = m.group(1)
                if line.startswith("running"):
                    ready.set()

        self.reader = threading.Thread(target=read, daemon=True)
        self.reader.start()
        if not ready.wait(20) or self.url is None:
            self.proc.kill()
            raise SystemExit(f"drivetwin did not start: {self.lines}")

    def stop(self) -> str:
        self.proc.send_signal(signal.SIGTERM)
        self.proc.wait(20)
        self.reader.join(5)
        line = next((l for l in self.lines if l.startswith("cell loop: ")), None)
        if line is None:
            raise SystemExit(f"no lateness line: {self.lines[-5:]}")
        return line.removeprefix("cell loop: ")


def mover(url: str, stop: threading.Event) -> None:
    """Drive 0 back and forth, one relative move each second."""
    call(url + "api/drives/0/motion/enable", "POST")
    sign = 1
    while not stop.wait(1.0):
        try:
            call(url + "api/drives/0/motion/move", "POST", {"target": 20000 * sign, "relative": True})
        except Exception:  # noqa: BLE001  (a move refused while the last one runs: next second)
            pass
        sign = -sign


def one_run(binary: str, cell: Path, seconds: float, tabs: int, rt: int | None) -> tuple[str, dict]:
    twin = Twin(binary, cell, rt)
    start = time.monotonic()
    stop = threading.Event()
    move = threading.Thread(target=mover, args=(twin.url, stop), daemon=True)
    move.start()
    info: dict = {}
    try:
        if tabs:
            from playwright.sync_api import sync_playwright
            with tempfile.TemporaryDirectory() as profile, sync_playwright() as pw:
                ctx = pw.chromium.launch_persistent_context(profile, executable_path=CHROMIUM, headless=True,
                                                            args=CHROMIUM_ARGS)
                t0 = time.monotonic()
                pages = []
                for _ in range(tabs):
                    page = ctx.new_page()
                    page.set_viewport_size({"width": 1400, "height": 1000})
                    page.goto(twin.url + "#drive/0")
                    page.wait_for_function("window.scope && window.scope.plot && window.scope.traces.length >= 4")
                    page.select_option("#scope-rate", "1000")
                    pages.append(page)
                info["load_s"] = round(time.monotonic() - t0, 2)
                time.sleep(max(0.0, seconds - (time.monotonic() - start)))
                info["scope_samples"] = [p.evaluate("(window.scope.buffers.get(0) || []).length") for p in pages]
                ctx.close()
        else:
            time.sleep(seconds)
        info["run_s"] = round(time.monotonic() - start, 1)
    finally:
        stop.set()
        move.join(3)
        figures = twin.stop()
    return figures, info


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=15.0)
    ap.add_argument("--tabs", type=int, default=5)
    ap.add_argument("--rt-priority", type=int, default=None)
    a = ap.parse_args()
    binary = os.environ.get("DRIVETWIN_BIN", str(Path(__file__).resolve().parent.parent / "target/release/drivetwin"))
    with tempfile.TemporaryDirectory() as d:
        cell = Path(d) / "cell.toml"
        cell.write_text("".join(f'[[drive]]\ndevice = "cmmp-as"\nnode = {n}\n\n' for n in range(1, DRIVES + 1)))
        print(f"{DRIVES} CMMP-AS, 125 kbit/s, {a.seconds:g} s per run, {a.tabs} tabs on drive 0's scope at 1 kHz,"
              f" loop {'SCHED_FIFO ' + str(a.rt_priority) if a.rt_priority else 'SCHED_OTHER'},"
              f" {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}")
        for r in range(1, a.rounds + 1):
            # Alternate which run goes first, so that neither always follows the browser's exit.
            order = [0, a.tabs] if r % 2 else [a.tabs, 0]
            for tabs in order:
                figures, info = one_run(binary, cell, a.seconds, tabs, a.rt_priority)
                label = f"{tabs} tabs" if tabs else "no tab"
                print(f"round {r} {label:>7}: {figures}" + (f"  {info}" if info else ""), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
