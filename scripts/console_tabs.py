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

Beside the lateness each run prints what the load and the machine's other work cannot blur:
the loop thread's (`cell`) wake-ups per second (voluntary context switches), the times it was
preempted per second (involuntary ones) and its CPU; the console's threads' CPU (`web`,
`web-worker`); and the browser's CPU (every process below this one but the twin), each over
the steady part of the run (after the tabs loaded), in percent of one CPU.
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


TICK = os.sysconf("SC_CLK_TCK")


def threads_of(pid: int) -> dict[str, list[int]]:
    """Per thread name: [voluntary switches, involuntary switches, CPU ticks], summed."""
    out: dict[str, list[int]] = {}
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            name = Path(f"/proc/{pid}/task/{tid}/comm").read_text().strip()
            status = Path(f"/proc/{pid}/task/{tid}/status").read_text()
            stat = Path(f"/proc/{pid}/task/{tid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        vol = int(re.search(r"^voluntary_ctxt_switches:\s*(\d+)", status, re.M).group(1))
        invol = int(re.search(r"^nonvoluntary_ctxt_switches:\s*(\d+)", status, re.M).group(1))
        cpu = int(stat[11]) + int(stat[12])  # utime, stime
        key = "web" if name.startswith("web") else name
        acc = out.setdefault(key, [0, 0, 0])
        for i, v in enumerate((vol, invol, cpu)):
            acc[i] += v
    return out


def descendants_cpu(root: int, leave_out: int) -> int:
    """CPU ticks of every process below `root` (the browser and its driver), `leave_out`'s
    tree excepted."""
    parent: dict[int, int] = {}
    ticks: dict[int, int] = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            f = Path(f"/proc/{d}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        parent[int(d)] = int(f[1])
        ticks[int(d)] = int(f[11]) + int(f[12])
    total = 0
    for pid, t in ticks.items():
        p, mine = pid, False
        while p in parent and p > 1:
            if p == leave_out:
                break
            if parent[p] == root:
                mine = p != leave_out
                break
            p = parent[p]
        if mine:
            total += t
    return total


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


class Steady:
    """The loop's, the console's and the browser's figures from now to `figures()`."""

    def __init__(self, twin: int):
        self.twin = twin
        self.t0 = time.monotonic()
        self.threads = threads_of(twin)
        self.browser = descendants_cpu(os.getpid(), twin)

    def figures(self) -> dict:
        dt = time.monotonic() - self.t0
        now = threads_of(self.twin)
        browser = descendants_cpu(os.getpid(), self.twin)
        d = {k: [b - a for a, b in zip(self.threads.get(k, [0, 0, 0]), v)] for k, v in now.items()}
        cell = d.get("cell", [0, 0, 0])
        pct = lambda ticks: round(100 * ticks / TICK / dt, 1)  # noqa: E731
        return {
            "loop_wakeups_per_s": round(cell[0] / dt),
            "loop_preempted_per_s": round(cell[1] / dt),
            "loop_cpu_pct": pct(cell[2]),
            "console_cpu_pct": pct(d.get("web", [0, 0, 0])[2]),
            "browser_cpu_pct": pct(browser - self.browser),
        }


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
                steady = Steady(twin.proc.pid)
                time.sleep(max(1.0, seconds - (time.monotonic() - start)))
                info.update(steady.figures())
                info["scope_samples"] = [p.evaluate("(window.scope.buffers.get(0) || []).length") for p in pages]
                ctx.close()
        else:
            time.sleep(min(2.0, seconds / 4))
            steady = Steady(twin.proc.pid)
            time.sleep(max(1.0, seconds - (time.monotonic() - start)))
            info.update(steady.figures())
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
    ap.add_argument("--drives", type=int, default=DRIVES, help="CMMP-AS on the bus (default 8)")
    a = ap.parse_args()
    binary = os.environ.get("DRIVETWIN_BIN", str(Path(__file__).resolve().parent.parent / "target/release/drivetwin"))
    with tempfile.TemporaryDirectory() as d:
        cell = Path(d) / "cell.toml"
        cell.write_text("".join(f'[[drive]]\ndevice = "cmmp-as"\nnode = {n}\n\n' for n in range(1, a.drives + 1)))
        print(f"{a.drives} CMMP-AS, 125 kbit/s, {a.seconds:g} s per run, {a.tabs} tabs on drive 0's scope at 1 kHz,"
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
