#!/usr/bin/env python3
"""Soak: a mixed cell at load for a given time, with clients coming and going, slow and
malformed clients and bus faults, while the twin's resident memory and open file descriptors
are sampled (issue 15, point 3).

The cell: a CMMP-AS (node 1), a Nanotec SMCI47-S (node 34) and a Kinco FD3 (node 5, also on
RS232 through a pty) on one socketcand bus, and a CMMO-ST on Modbus TCP. The clients, all at
once:
  - python-canopen SDO loops on the three CAN drives (reads, and writes that are refused),
  - a pyserial client polling the Kinco's statusword over RS232 (KINCO-232 telegrams),
  - python-can connections that come, see a heartbeat and go, every 0.3 s,
  - a socketcand client that never reads (the twin must drop it, not wait for it),
  - raw connections that send garbage to both servers, and NMT resets of both nodes,
  - a pymodbus FHPP client that exchanges FC 0x17 and reconnects every few seconds.
At the end every drive must still answer, resident memory must be flat after the warm-up
(growth at most --max-growth-kib), the descriptors back at their baseline, and the cell loop
must have served 99 % of its due timers within --max-late-ms (the twin prints its lateness
figures when it stops).

  scripts/soak.py --seconds 120                 # the test command's run
  scripts/soak.py --seconds 3600 --report docs/soak.md
"""

from __future__ import annotations

import argparse
import contextlib
import os
import random
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
HOST = "127.0.0.1"


def free_port() -> int:
    with socket.socket() as s:
        s.bind((HOST, 0))
        return s.getsockname()[1]


def rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    return 0


def fds(pid: int) -> int:
    return len(os.listdir(f"/proc/{pid}/fd"))


class Counters:
    def __init__(self):
        self.lock = threading.Lock()
        self.n: dict[str, int] = {}

    def add(self, key: str, k: int = 1):
        with self.lock:
            self.n[key] = self.n.get(key, 0) + k


def sdo_loop(port, eds, node_id, stop, c: Counters, rng):
    import canopen

    net = canopen.Network()
    net.NOTIFIER_CYCLE = 0.05
    net.connect(interface="socketcand", host=HOST, port=port, channel="vcan0")
    node = net.add_node(node_id, str(eds))
    node.sdo.RESPONSE_TIMEOUT = 2.0
    try:
        while not stop.is_set():
            try:
                node.sdo[0x6041].raw
                node.sdo.upload(0x1018, 1)
                c.add(f"sdo ok node {node_id}")
                if rng.random() < 0.1:
                    try:
                        node.sdo.download(0x6041, 0, b"\x00\x00")  # read-only: refused
                        c.add("unexpected write accepted")
                    except canopen.SdoAbortedError:
                        c.add("sdo refused as expected")
            except canopen.SdoAbortedError as e:
                c.add(f"sdo abort node {node_id}: {e.code:08X}")
            except canopen.SdoCommunicationError:
                c.add(f"sdo timeout node {node_id}")
    finally:
        net.disconnect()


def churn_loop(port, stop, c: Counters):
    import can

    # A client comes, sees node 1's heartbeat (100 ms) and goes. It sends no SDO: the SDO
    # loops own the SDO channels (CiA 301: one client per channel).
    while not stop.is_set():
        bus = can.Bus(interface="socketcand", host=HOST, port=port, channel="vcan0")
        deadline = time.monotonic() + 1.0
        while time.monotonic() < deadline:
            m = bus.recv(0.2)
            if m is not None and m.arbitration_id == 0x701:
                c.add("churn saw a heartbeat")
                break
        bus.shutdown()
        c.add("churn connections")
        stop.wait(0.3)


def slow_client_loop(port, stop, c: Counters):
    while not stop.is_set():
        s = socket.create_connection((HOST, port))
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        s.sendall(b"< open vcan0 >< rawmode >")
        c.add("slow clients")
        # Never read: the twin must drop this connection once its queue for it is full,
        # without slowing the bus for the others.
        if stop.wait(10.0):
            s.close()
            break
        s.close()


def garbage_loop(can_port, modbus_port, stop, c: Counters, rng, resets=True):
    import can

    while not stop.is_set():
        for port in (can_port, modbus_port):
            try:
                s = socket.create_connection((HOST, port), timeout=1.0)
                s.sendall(bytes(rng.randrange(256) for _ in range(rng.randrange(1, 400))))
                s.close()
                c.add("garbage connections")
            except OSError:
                c.add("garbage refused")
        # NMT reset of both nodes now and then: they boot again and go on.
        if resets and rng.random() < 0.2:
            bus = can.Bus(interface="socketcand", host=HOST, port=can_port, channel="vcan0")
            bus.send(can.Message(arbitration_id=0, data=[0x81, 0], is_extended_id=False))
            bus.shutdown()
            c.add("nmt resets")
        stop.wait(1.0)


def rs232_loop(path: Path, stop, c: Counters):
    """Polls the Kinco's statusword (6041h) over RS232 the way public Kinco drivers do (the
    station is the node-ID, 5)."""
    import serial

    body = bytes([5, 0x40, 0x41, 0x60, 0, 0, 0, 0, 0])
    telegram = body + bytes([(-sum(body)) & 0xFF])
    with serial.Serial(str(path), 38400, timeout=0.2) as port:
        while not stop.is_set():
            port.reset_input_buffer()
            port.write(telegram)
            a = port.read(10)
            ok = len(a) == 10 and sum(a) & 0xFF == 0 and a[1] == 0x4B
            c.add("rs232 ok" if ok else "rs232 unanswered")


def modbus_loop(port, stop, c: Counters):
    from pymodbus.client import ModbusTcpClient

    while not stop.is_set():
        client = ModbusTcpClient(HOST, port=port, timeout=2, retries=0)
        if not client.connect():
            c.add("modbus connect failed")
            stop.wait(0.5)
            continue
        until = time.monotonic() + 5.0
        while time.monotonic() < until and not stop.is_set():
            try:
                rr = client.readwrite_registers(read_address=0, read_count=4, write_address=0,
                                                values=[0x0300, 0, 0, 0])
                c.add("modbus error" if rr.isError() else "modbus ok")
            except Exception:  # a connection the twin closed: reconnect
                c.add("modbus exception")
                break
        client.close()


def main() -> int:
    import logging

    logging.getLogger("can").setLevel(logging.ERROR)
    logging.getLogger("canopen").setLevel(logging.CRITICAL)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=120)
    ap.add_argument("--bin", default=os.environ.get("DRIVETWIN_BIN",
                                                    REPO / "target" / "release" / "drivetwin"))
    ap.add_argument("--max-growth-kib", type=int, default=4096)
    ap.add_argument("--max-late-ms", type=float, default=16.0,
                    help="bound on the cell loop's 99th percentile timer lateness")
    ap.add_argument("--report", type=Path)
    ap.add_argument("--no-resets", action="store_true", help="leave out the NMT resets")
    args = ap.parse_args()

    tmp = Path(tempfile.mkdtemp(prefix="soak-"))
    can_port, modbus_port = free_port(), free_port()
    cell = tmp / "soak.toml"
    cell.write_text(f"""
[bus]
socketcand = "{HOST}:{can_port}"
channel = "vcan0"

[[drive]]
device = "cmmp-as"
node = 1
[drive.objects]
"1017:00" = 100

[[drive]]
device = "nanotec-smci47s"
node = 34
[drive.objects]
"1017:00" = 100

[[drive]]
device = "kinco-fd3"
node = 5
rs232 = "{tmp / 'ttyKINCO'}"
[drive.objects]
"1017:00" = 100

[[drive]]
device = "cmmo-st"
modbus = "{HOST}:{modbus_port}"
modbus_timeout_ms = 0
""")
    eds = {}
    for dev in ("cmmp-as", "nanotec-smci47s", "kinco-fd3"):
        out = subprocess.run([str(args.bin), "eds", "--device", dev], check=True,
                             capture_output=True, text=True).stdout
        eds[dev] = tmp / f"{dev}.eds"
        eds[dev].write_text(out)

    err = open(tmp / "twin.stderr", "wb")
    twin = subprocess.Popen([str(args.bin), "run", "--config", str(cell)],
                            stdout=subprocess.PIPE, stderr=err, text=True)
    started = time.monotonic()
    while True:
        line = twin.stdout.readline()
        if not line or "running" in line:
            break
        if time.monotonic() - started > 10:
            break
    twin_lines: list[str] = []
    threading.Thread(target=lambda: twin_lines.extend(twin.stdout), daemon=True).start()
    if twin.poll() is not None:
        print((tmp / "twin.stderr").read_text(), file=sys.stderr)
        return 1

    stop = threading.Event()
    c = Counters()
    rng = random.Random(20261127)
    threads = [
        threading.Thread(target=sdo_loop, args=(can_port, eds["cmmp-as"], 1, stop, c, random.Random(1))),
        threading.Thread(target=sdo_loop, args=(can_port, eds["nanotec-smci47s"], 34, stop, c, random.Random(2))),
        threading.Thread(target=sdo_loop, args=(can_port, eds["kinco-fd3"], 5, stop, c, random.Random(3))),
        threading.Thread(target=rs232_loop, args=(tmp / "ttyKINCO", stop, c)),
        threading.Thread(target=churn_loop, args=(can_port, stop, c)),
        threading.Thread(target=slow_client_loop, args=(can_port, stop, c)),
        threading.Thread(target=garbage_loop, args=(can_port, modbus_port, stop, c, rng, not args.no_resets)),
        threading.Thread(target=modbus_loop, args=(modbus_port, stop, c)),
    ]
    baseline_fds = fds(twin.pid)
    for t in threads:
        t.start()
    samples = []
    t0 = time.monotonic()
    while time.monotonic() - t0 < args.seconds and twin.poll() is None:
        samples.append((time.monotonic() - t0, rss_kib(twin.pid), fds(twin.pid)))
        time.sleep(1.0)
    stop.set()
    for t in threads:
        t.join(15)
    # Closed connections leave the twin's loop.
    settle = time.monotonic() + 5.0
    while twin.poll() is None and fds(twin.pid) > baseline_fds + 2 and time.monotonic() < settle:
        time.sleep(0.1)
    alive = twin.poll() is None
    end_fds = fds(twin.pid) if alive else -1
    if alive and end_fds > baseline_fds + 2:
        ss = subprocess.run(["ss", "-tanp"], capture_output=True, text=True).stdout
        print("\n".join(l for l in ss.splitlines() if f"pid={twin.pid}," in l), file=sys.stderr)
        kinds: dict[str, int] = {}
        for f in os.listdir(f"/proc/{twin.pid}/fd"):
            with contextlib.suppress(OSError):
                k = os.readlink(f"/proc/{twin.pid}/fd/{f}").split(":")[0]
                kinds[k] = kinds.get(k, 0) + 1
        print(f"open descriptors: {kinds}", file=sys.stderr)

    # Every drive still answers.
    answers = {}
    if alive:
        import can
        from pymodbus.client import ModbusTcpClient

        bus = can.Bus(interface="socketcand", host=HOST, port=can_port, channel="vcan0")
        for node in (1, 34, 5):
            bus.send(can.Message(arbitration_id=0x600 + node,
                                 data=bytes.fromhex("4018100100000000"), is_extended_id=False))
            deadline = time.monotonic() + 2
            answers[node] = False
            while time.monotonic() < deadline:
                m = bus.recv(0.2)
                if m is not None and m.arbitration_id == 0x580 + node:
                    answers[node] = True
                    break
        bus.shutdown()
        mb = ModbusTcpClient(HOST, port=modbus_port, timeout=2, retries=0)
        answers["cmmo-st"] = mb.connect() and not mb.read_holding_registers(0, count=4).isError()
        mb.close()
        twin.send_signal(signal.SIGTERM)
        twin.wait(10)
        time.sleep(0.2)  # the reader thread takes the last lines

    # "cell loop: N timers served, late p50 ≤ …, p99 ≤ …µs, …" (cell/lateness.rs)
    loop_line = next((l.strip() for l in twin_lines if l.startswith("cell loop:")), "")
    p99 = re.search(r"p99 ≤ ([0-9.]+)(µs|ms|s)", loop_line)
    p99_ms = (float(p99.group(1)) * {"µs": 1e-3, "ms": 1.0, "s": 1e3}[p99.group(2)]) if p99 else float("inf")

    warm = [s for s in samples if s[0] >= min(20.0, args.seconds / 4)]
    growth = (warm[-1][1] - warm[0][1]) if len(warm) >= 2 else 0
    peak_fds = max((s[2] for s in samples), default=0)
    ok = (alive and all(answers.values()) and growth <= args.max_growth_kib
          and p99_ms <= args.max_late_ms and c.n.get("rs232 ok", 0) > 0
          and end_fds <= baseline_fds + 2 and c.n.get("unexpected write accepted", 0) == 0
          and not any(k.startswith("sdo timeout") for k in c.n))
    lines = [
        f"Soak of {args.seconds:.0f} s ({time.strftime('%Y-%m-%d', time.gmtime())}, {os.cpu_count()} CPUs): "
        f"{'PASS' if ok else 'FAIL'}",
        "",
        f"- twin alive at the end: {alive}; every drive answered: {answers}",
        f"- resident memory after the warm-up: {warm[0][1] if warm else 0} KiB -> "
        f"{warm[-1][1] if warm else 0} KiB (growth {growth} KiB, bound {args.max_growth_kib} KiB)",
        f"- file descriptors: {baseline_fds} at the start, at most {peak_fds} under load, "
        f"{end_fds} after the clients left",
        f"- the cell loop's timers: {loop_line.removeprefix('cell loop: ') or 'no figures printed'} "
        f"(bound on p99: {args.max_late_ms} ms)",
        "- client counts: " + ", ".join(f"{k} {v}" for k, v in sorted(c.n.items())),
    ]
    text = "\n".join(lines)
    print(text)
    if args.report:
        args.report.write_text("# Soak report\n\n" + text + "\n")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
