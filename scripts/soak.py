#!/usr/bin/env python3
"""Soak: a mixed cell at load for a given time, with clients coming and going, slow and
malformed clients and bus faults, while the twin's resident memory and open file descriptors
are sampled.

The cell: a CMMP-AS (node 1), a Nanotec SMCI47-S (node 34) and a Kinco FD3 (node 5, also on
RS232 through a pty) on one socketcand bus, a CMMO-ST on Modbus TCP, and, where the machine
allows it (root, iproute2, pysoem), a CMMP-AS on EtherCAT over a veth pair. The clients, all at
once:
  - python-canopen SDO loops on the three CAN drives (reads, and writes that are refused),
  - a pyserial client polling the Kinco's statusword over RS232 (KINCO-232 telegrams),
  - python-can connections that come, see a heartbeat and go, every 0.3 s,
  - a socketcand client that never reads (the twin must drop it, not wait for it),
  - raw connections that send garbage to both servers, and NMT resets of both nodes,
  - a pymodbus FHPP client that exchanges FC 0x17 and reconnects every few seconds,
  - a pysoem master (a process of its own, so that the other clients' threads do not hold it
    off its cycle) that takes the EtherCAT CMMP-AS to Op in cyclic synchronous position,
    enables it and cycles its PDOs every --ecat-cycle-ms, reading 1018h:01 over CoE now and
    then; it counts frames that did not come back within 20 ms (lost) and frames with a wrong
    working counter.
At the end every drive must still answer, the EtherCAT frames lost at most --max-lost-permille
of the cycles, no wrong working counter, resident memory must be flat after the warm-up
(growth at most --max-growth-kib), the descriptors back at their baseline, and the cell loop
must have served 99 % of its due timers within --max-late-ms (the twin prints its lateness
figures when it stops).

  scripts/soak.py --seconds 30                  # the test command's run
  scripts/soak.py --seconds 120                 # the default
  scripts/soak.py --seconds 3600 --report docs/soak-report.md
  scripts/soak 3600                             # the same, report into docs/soak-report.md
"""

from __future__ import annotations

import argparse
import contextlib
import json
import shutil
import struct
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


def tenths(samples: list, seconds: float) -> list:
    """(time, resident KiB) of the samples nearest to each tenth of the run, so a report
    shows whether memory levels off or keeps growing."""
    if not samples:
        return []
    picked = [min(samples, key=lambda s: abs(s[0] - seconds * k / 10)) for k in range(1, 11)]
    return [(t, kib) for t, kib, _ in picked]


def progress_shown(stderr_is_terminal: bool, ci: str | None) -> bool:
    """Progress is drawn only for a person at a terminal: standard error is one and `CI` is
    unset, empty, 0 or false (the rule of the binary's progress bars, commands/progress.rs;
    CI runners that give jobs a pseudo-terminal set CI)."""
    in_ci = ci is not None and ci.strip() not in ("", "0", "false")
    return stderr_is_terminal and not in_ci


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


def ecat_master(iface: str, seconds: float, cycle_ms: float) -> dict:
    """The pysoem master of the EtherCAT CMMP-AS (run with --ecat-master in a process of its
    own): Pre-Op SDOs, CSP PDOs (RxPDO3 1602h: controlword + target, TxPDO3 1A02h: statusword +
    position), Op, enable, then a PDO exchange every `cycle_ms` holding the position, and
    1018h:01 read over CoE every 500 cycles. Returns its counters."""
    import pysoem

    r = {"cycles": 0, "lost": 0, "wrong_wkc": 0, "left_op": 0, "sdo_ok": 0, "sdo_failed": 0,
         "answered_at_end": False, "error": ""}
    errors = (pysoem.SdoError, pysoem.MailboxError, pysoem.PacketError, pysoem.WkcError)
    m = pysoem.Master()
    m.open(iface)
    try:
        if m.config_init() != 1:
            r["error"] = "config_init found no slave"
            return r
        s = m.slaves[0]
        for index, pdo in ((0x1C12, 0x1602), (0x1C13, 0x1A02)):
            s.sdo_write(index, 0, bytes([0]))
            s.sdo_write(index, 1, struct.pack("<H", pdo))
            s.sdo_write(index, 0, bytes([1]))
        s.sdo_write(0x6060, 0, bytes([8]))
        m.config_map()
        if m.state_check(pysoem.SAFEOP_STATE, 2_000_000) != pysoem.SAFEOP_STATE:
            r["error"] = f"no Safe-Op (AL status code {s.al_status:#x})"
            return r
        # A frame is lost when it is not back within 20 ms: the bound on the cell loop's p99
        # lateness (--max-late-ms, 16 ms) and a margin.
        timeout_us = int(max(20.0, 5 * cycle_ms) * 1000)

        def cycle(cw, target):
            s.output = struct.pack("<Hi", cw, target)
            m.send_processdata()
            wkc = m.receive_processdata(timeout_us)
            sw, pos = struct.unpack("<Hi", bytes(s.input))
            return wkc, sw, pos

        m.state = pysoem.OP_STATE
        _, _, pos = cycle(0, 0)
        m.write_state()
        for _ in range(400):
            _, _, pos = cycle(0, pos)
            if m.read_state() == pysoem.OP_STATE:
                break
            time.sleep(cycle_ms / 1000)
        if s.state != pysoem.OP_STATE:
            r["error"] = f"no Op (state {s.state:#x}, AL status code {s.al_status:#x})"
            return r
        expected = m.expected_wkc
        cw = 0x06
        dt = cycle_ms / 1000
        nxt = time.monotonic()
        end = nxt + seconds
        while time.monotonic() < end:
            wkc, sw, actual = cycle(cw, pos)
            r["cycles"] += 1
            if wkc < 0:
                r["lost"] += 1
            elif wkc != expected:
                r["wrong_wkc"] += 1
                if m.read_state() != pysoem.OP_STATE:
                    # Fell back (watchdog, SYNC): counted, acknowledged and taken back to Op.
                    r["left_op"] += 1
                    s.state = pysoem.SAFEOP_STATE + pysoem.STATE_ACK
                    s.write_state()
                    s.state = pysoem.OP_STATE
                    s.write_state()
            # CiA 402: fault reset, shutdown, switch on, enable; the target follows the actual
            # position until the drive is enabled, then holds it.
            state = sw & 0x6F
            if sw & 0x08:
                cw = 0x80 if cw != 0x80 else 0x00
            elif state in (0x23, 0x27):
                cw = 0x0F
            elif state == 0x21:
                cw = 0x07
            else:
                cw = 0x06
            if state != 0x27:
                pos = actual
            if r["cycles"] % 500 == 0:
                try:
                    s.sdo_read(0x1018, 1)
                    r["sdo_ok"] += 1
                except errors:
                    r["sdo_failed"] += 1
            nxt += dt
            delay = nxt - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            else:
                nxt = time.monotonic()  # held off the CPU: skip the missed cycles, no burst
        try:
            r["answered_at_end"] = int.from_bytes(s.sdo_read(0x1018, 1), "little") == 0x1D
        except errors as e:
            r["error"] = f"1018h:01 at the end: {e}"
        m.state = pysoem.INIT_STATE
        m.write_state()
    finally:
        m.close()
    return r


@contextlib.contextmanager
def veth_pair(want: str):
    """(twin-side, master-side) interfaces of a veth pair in this namespace, or None where the
    machine does not allow one (not root, no iproute2, no pysoem) and `want` is "auto"."""
    why = ""
    if os.geteuid() != 0:
        why = "not root (raw sockets)"
    elif shutil.which("ip") is None:
        why = "no iproute2"
    else:
        try:
            import pysoem  # noqa: F401
        except ImportError:
            why = "pysoem is not installed"
    tag = f"{os.getpid() % 100000}"
    twin_if, master_if = f"dtwSa{tag}", f"dtwSb{tag}"
    if not why:
        for step in (("link", "add", master_if, "type", "veth", "peer", "name", twin_if),
                     ("link", "set", twin_if, "up"), ("link", "set", master_if, "up")):
            p = subprocess.run(["ip", *step], capture_output=True, text=True)
            if p.returncode != 0:
                why = f"ip {' '.join(step)}: {p.stderr.strip()}"
                break
    try:
        if why and want == "on":
            raise SystemExit(f"EtherCAT asked for, but {why}")
        if why:
            print(f"soak: no EtherCAT drive ({why})", file=sys.stderr)
        yield None if why else (twin_if, master_if)
    finally:
        subprocess.run(["ip", "link", "del", master_if], capture_output=True)


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--ecat-master":
        iface, seconds, cycle_ms = sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
        print(json.dumps(ecat_master(iface, seconds, cycle_ms)), flush=True)
        return 0
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
    ap.add_argument("--ethercat", choices=("auto", "on", "off"), default="auto",
                    help="the CMMP-AS on EtherCAT (veth pair, pysoem): where the machine allows it")
    ap.add_argument("--ecat-cycle-ms", type=float, default=2.0)
    ap.add_argument("--max-lost-permille", type=float, default=1.0,
                    help="bound on the EtherCAT frames lost, per mille of the cycles")
    args = ap.parse_args()
    if args.ethercat == "off":
        return soak(args, None)
    with veth_pair(args.ethercat) as pair:
        return soak(args, pair)


def soak(args, pair) -> int:

    tmp = Path(tempfile.mkdtemp(prefix="soak-"))
    can_port, modbus_port = free_port(), free_port()
    cell = tmp / "soak.toml"
    cell.write_text(f"""
[bus]
socketcand = "{HOST}:{can_port}"
channel = "vcan0"
# No bitrate: the bus runs at its drives' 1 Mbit/s (the Nanotec's switches fix it).

[[drive]]
device = "cmmp-as"
node = 1
[drive.switches]              # DIP6/DIP7 ON: 1 Mbit/s; DIP8 ON: CANopen; node 1
variant = "m3"
on = [6, 7, 8]
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
"2F81:00" = 100               # CAN_Baudrate: 1 Mbit/s

[[drive]]
device = "cmmo-st"
modbus = "{HOST}:{modbus_port}"
modbus_timeout_ms = 0
""")
    if pair:
        with cell.open("a") as f:
            f.write(f"""
[[drive]]
device = "cmmp-as"
node = 2
interfaces = ["ethercat"]
ethercat = "{pair[0]}"
[drive.objects]
"6510:F0" = 0x80
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
    ecat = None
    if pair:
        ecat = subprocess.Popen([sys.executable, __file__, "--ecat-master", pair[1], str(args.seconds),
                                 str(args.ecat_cycle_ms)], stdout=subprocess.PIPE, text=True)
    for t in threads:
        t.start()
    samples = []
    # Progress on a terminal (one line, rewritten each second); nothing in CI or a log.
    progress = progress_shown(sys.stderr.isatty(), os.environ.get("CI"))
    t0 = time.monotonic()
    while time.monotonic() - t0 < args.seconds and twin.poll() is None:
        samples.append((time.monotonic() - t0, rss_kib(twin.pid), fds(twin.pid)))
        if progress:
            at, rss, fd = samples[-1]
            print(f"\rsoak: {at:.0f} / {args.seconds:.0f} s, RSS {rss} KiB, {fd} descriptors ",
                  end="", file=sys.stderr, flush=True)
        time.sleep(1.0)
    if progress:
        print(file=sys.stderr)
    stop.set()
    for t in threads:
        t.join(15)
    ecat_figures = None
    if ecat:
        try:
            out, _ = ecat.communicate(timeout=60)
            ecat_figures = json.loads(out.strip().splitlines()[-1])
        except (subprocess.TimeoutExpired, ValueError, IndexError) as e:
            ecat.kill()
            ecat_figures = {"error": f"the pysoem master: {e!r}"}
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

    ecat_ok = True
    if ecat_figures is not None:
        n = ecat_figures.get("cycles", 0)
        lost_bound = args.max_lost_permille / 1000 * n
        twin_lost = (tmp / "twin.stderr").read_text(errors="replace").count("frame lost")
        ecat_figures["twin_tx_lost"] = twin_lost
        ecat_ok = (not ecat_figures.get("error") and n > 0 and ecat_figures.get("answered_at_end")
                   and ecat_figures.get("lost", 0) + twin_lost <= lost_bound
                   and ecat_figures.get("wrong_wkc", 0) == 0)
    warm = [s for s in samples if s[0] >= min(20.0, args.seconds / 4)]
    growth = (warm[-1][1] - warm[0][1]) if len(warm) >= 2 else 0
    peak_fds = max((s[2] for s in samples), default=0)
    ok = (alive and all(answers.values()) and growth <= args.max_growth_kib
          and p99_ms <= args.max_late_ms and c.n.get("rs232 ok", 0) > 0
          and end_fds <= baseline_fds + 2 and c.n.get("unexpected write accepted", 0) == 0
          and not any(k.startswith("sdo timeout") for k in c.n) and ecat_ok)
    lines = [
        f"Soak of {args.seconds:.0f} s ({time.strftime('%Y-%m-%d', time.gmtime())}, {os.cpu_count()} CPUs): "
        f"{'PASS' if ok else 'FAIL'}",
        "",
        f"- twin alive at the end: {alive}; every drive answered: {answers}",
        f"- resident memory after the warm-up: {warm[0][1] if warm else 0} KiB -> "
        f"{warm[-1][1] if warm else 0} KiB (growth {growth} KiB, bound {args.max_growth_kib} KiB)",
        "- resident memory at each tenth of the run (s: KiB): " + ", ".join(
            f"{t:.0f}: {kib}" for t, kib in tenths(samples, args.seconds)),
        f"- file descriptors: {baseline_fds} at the start, at most {peak_fds} under load, "
        f"{end_fds} after the clients left",
        f"- the cell loop's timers: {loop_line.removeprefix('cell loop: ') or 'no figures printed'} "
        f"(bound on p99: {args.max_late_ms} ms)",
        "- client counts: " + ", ".join(f"{k} {v}" for k, v in sorted(c.n.items())),
    ]
    if ecat_figures is None:
        lines.append("- EtherCAT: no drive (--ethercat off)" if args.ethercat == "off" else
                     "- EtherCAT: no drive (the machine does not allow a veth pair and pysoem here)")
    else:
        e = ecat_figures
        lines.append(
            f"- EtherCAT (CMMP-AS, CSP PDOs every {args.ecat_cycle_ms} ms, pysoem): {e.get('cycles', 0)} cycles, "
            f"{e.get('lost', 0)} frames lost at the master and {e.get('twin_tx_lost', 0)} at the twin's send queue "
            f"(bound {args.max_lost_permille}‰ of the cycles), {e.get('wrong_wkc', 0)} wrong working counters "
            f"({e.get('left_op', 0)} times out of Op), CoE reads {e.get('sdo_ok', 0)} ok / {e.get('sdo_failed', 0)} failed, "
            f"answered at the end: {e.get('answered_at_end')}" + (f"; error: {e['error']}" if e.get("error") else ""))
    text = "\n".join(lines)
    print(text)
    if args.report:
        args.report.write_text(
            "# Soak report\n\nWritten by `scripts/soak "
            f"{args.seconds:.0f} --report` (scripts/soak.py: the cell, the clients and the bounds are "
            "described there).\n\n" + text + "\n")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
