"""Fixtures for the interop tests: the real drivetwin binary, driven by clients nobody here wrote.

Every test starts its own `drivetwin run` on a free loopback port with its own state directory,
talks to it over socketcand with python-canopen / python-can (or raw TCP), and stops it with
SIGTERM, checking that it stopped cleanly.

The tests cite the manuals: `seeds/NNN_….txt` is a manual's text and `spec/….md` its English
extract, both kept beside the project in `../shared` (not in this repository); `spec/vectors.md`
is the catalogue of the manuals' worked examples, named in the tests by their IDs.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]
DRIVETWIN_BIN = Path(os.environ.get("DRIVETWIN_BIN", REPO_ROOT / "target" / "release" / "drivetwin"))
CHANNEL = "vcan0"
HOST = "127.0.0.1"
START_TIMEOUT = 10.0
STOP_TIMEOUT = 5.0
SDO_TIMEOUT = 2.0  # python-canopen client response timeout, generous for loaded machines


# The cell FMU's library (crates/cell-fmu) of the profile the binary under test was built with:
# beside it (target/release/, or target/dist/ where the test command tests the dist binary), where
# `drivetwin fmu` takes it unless --library names one. DRIVETWIN_CELL_LIBRARY names one already
# built (the test command names the dist build's, so packing a cell never compiles).
_BUILT = DRIVETWIN_BIN.resolve().parent
CELL_PROFILE = _BUILT.name if _BUILT.parent == (REPO_ROOT / "target").resolve() else "release"
CELL_LIBRARY = Path(os.environ.get("DRIVETWIN_CELL_LIBRARY",
                                   REPO_ROOT / "target" / CELL_PROFILE / "libdrivetwin_cell.so"))


@pytest.fixture(scope="session")
def cell_library() -> Path:
    """CELL_LIBRARY, built from source once a session by scripts/cell-fmu in the binary's
    profile (a no-op when it is fresh) unless DRIVETWIN_CELL_LIBRARY names it."""
    if "DRIVETWIN_CELL_LIBRARY" not in os.environ:
        subprocess.run([str(REPO_ROOT / "scripts" / "cell-fmu")], check=True, cwd=REPO_ROOT,
                       env={**os.environ, "CELL_FMU_PROFILE": CELL_PROFILE})
    if not CELL_LIBRARY.is_file():
        pytest.fail(f"{CELL_LIBRARY} is missing: run scripts/cell-fmu or set DRIVETWIN_CELL_LIBRARY",
                    pytrace=False)
    return CELL_LIBRARY


@pytest.fixture(scope="session", autouse=True)
def drivetwin_binary() -> Path:
    """Every test needs the built binary; say how to get it instead of failing obscurely."""
    if not (DRIVETWIN_BIN.is_file() and os.access(DRIVETWIN_BIN, os.X_OK)):
        pytest.fail(f"{DRIVETWIN_BIN} is missing: run `cargo build --release -p drivetwin` or set "
                    "DRIVETWIN_BIN", pytrace=False)
    return DRIVETWIN_BIN


def free_port() -> int:
    """A loopback TCP port nobody listens on right now (bind to port 0, read it, close)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((HOST, 0))
        return s.getsockname()[1]


def run_cli(*args: str, timeout: float = 30.0, check: bool = False) -> subprocess.CompletedProcess:
    """Run a one-shot drivetwin command (eds, sdo, nmt, monitor, a virtual-clock run)."""
    return subprocess.run(
        [str(DRIVETWIN_BIN), *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=check,
    )


def read_to_cr(f) -> bytes:
    """One answer of the CMMP-AS CI terminal from a file-like `f`, up to and with its CR (the
    device ends answers with CR alone; `readline` would wait for an LF that never comes)."""
    line = b""
    while not line.endswith(b"\r"):
        b = f.read(1)
        if not b:
            break
        line += b
    return line


def wait_until(predicate, timeout: float, interval: float = 0.02, what: str = "condition"):
    """Poll `predicate` until it returns something truthy; fail the test after `timeout` s."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout} s waiting for {what}")
        time.sleep(interval)


class Twin:
    """One running `drivetwin run` process with a socketcand server on 127.0.0.1:port."""

    def __init__(self, state_dir: Path, log_dir: Path, device: str = "cmmp-as", node: int = 1,
                 config: Path | None = None, trace: Path | None = None, extra: tuple[str, ...] = (),
                 prefix: tuple[str, ...] | list[str] = ()):
        self.state_dir = Path(state_dir)
        self.device = device
        self.node = node
        self.config = config
        self.trace = trace
        self.extra = tuple(extra)
        self.prefix = tuple(prefix)  # e.g. realtime_prefix()
        self.log_dir = Path(log_dir)
        self.port: int | None = None
        self.proc: subprocess.Popen | None = None
        self.stdout_lines: list[str] = []
        self._ready = threading.Event()
        self._reader: threading.Thread | None = None
        self._starts = 0

    @property
    def addr(self) -> str:
        return f"{HOST}:{self.port}"

    def _args(self) -> list[str]:
        args = [*self.prefix, str(DRIVETWIN_BIN), "run", "--socketcand", self.addr, "--channel", CHANNEL,
                "--state-dir", str(self.state_dir)]
        if self.config is not None:
            args += ["--config", str(self.config)]
        else:
            args += ["--device", self.device, "--node", str(self.node)]
        if self.trace is not None:
            args += ["--trace", str(self.trace)]
        return args + list(self.extra)

    def _read_stdout(self, proc: subprocess.Popen, lines: list[str], ready: threading.Event):
        for line in proc.stdout:
            lines.append(line.rstrip("\n"))
            if line.startswith("socketcand server on"):
                ready.set()
        ready.set()  # EOF: the process ended (start() looks at poll())

    def start(self, port: int | None = None) -> "Twin":
        """Start the process and wait for its "socketcand server on" line.

        With no port given, a free one is picked; if another process grabs it between the pick
        and the bind, the start is retried on a new port.
        """
        assert self.proc is None or self.proc.poll() is not None, "already running"
        attempts = 1 if port is not None else 5
        last_error = ""
        for _ in range(attempts):
            self.port = port if port is not None else free_port()
            self._starts += 1
            stderr_path = self.log_dir / f"drivetwin-{self.port}-{self._starts}.stderr"
            self.stderr_path = stderr_path
            self.stdout_lines = []
            self._ready = threading.Event()
            with open(stderr_path, "wb") as err:
                self.proc = subprocess.Popen(self._args(), stdout=subprocess.PIPE, stderr=err,
                                             text=True, bufsize=1)
            self._reader = threading.Thread(target=self._read_stdout,
                                            args=(self.proc, self.stdout_lines, self._ready),
                                            daemon=True)
            self._reader.start()
            self._ready.wait(START_TIMEOUT)
            if self.proc.poll() is None and any(
                    l.startswith("socketcand server on") for l in self.stdout_lines):
                expected = f"socketcand server on {self.addr}, channel {CHANNEL}"
                assert expected in self.stdout_lines, self.stdout_lines
                return self
            if self.proc.poll() is None:
                self.proc.kill()
                self.proc.wait()
                pytest.fail(f"drivetwin did not print 'socketcand server on' within {START_TIMEOUT} s:"
                            f" stdout={self.stdout_lines} stderr={self.stderr()}")
            last_error = f"exit {self.proc.returncode}: {self.stderr()}"
            if "in use" not in self.stderr().lower():
                break  # not a lost race for the port: retrying will not help
        pytest.fail(f"drivetwin did not start: {last_error}")

    def stderr(self) -> str:
        try:
            return Path(self.stderr_path).read_text(errors="replace")
        except (OSError, AttributeError):
            return ""

    def running(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def stop(self, check: bool = True) -> int:
        """SIGTERM, wait, SIGKILL on timeout; with check, assert a clean stop (exit 0, "stopped")."""
        proc = self.proc
        if proc is None:
            return 0
        killed = False
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
                killed = True
        if self._reader is not None:
            self._reader.join(2)
        code = proc.returncode
        self.proc = None
        if check:
            assert not killed, f"drivetwin ignored SIGTERM for {STOP_TIMEOUT} s; stderr={self.stderr()}"
            assert code == 0, f"drivetwin exited with {code}; stderr={self.stderr()}"
            assert "stopped" in self.stdout_lines, self.stdout_lines
        return code


@pytest.fixture
def launch(tmp_path):
    """Factory: launch(device=..., node=..., ...) starts a Twin; all are stopped (and checked) at
    teardown."""
    twins: list[Twin] = []
    log_dir = tmp_path / "logs"
    log_dir.mkdir()

    def _launch(device: str = "cmmp-as", node: int = 1, state_dir: Path | None = None,
                start: bool = True, **kw) -> Twin:
        sd = state_dir if state_dir is not None else tmp_path / f"state{len(twins)}"
        sd.mkdir(parents=True, exist_ok=True)
        twin = Twin(sd, log_dir, device=device, node=node, **kw)
        twins.append(twin)
        if start:
            twin.start()
        return twin

    yield _launch
    failures = []
    for twin in twins:
        if twin.proc is None:
            continue
        was_running = twin.running()
        code = twin.stop(check=False)
        if not was_running:
            failures.append(f"drivetwin died during the test (exit {code}); stderr={twin.stderr()[-2000:]}")
        elif code != 0:
            failures.append(f"drivetwin did not stop cleanly (exit {code}); stderr={twin.stderr()[-2000:]}")
        elif "stopped" not in twin.stdout_lines:
            failures.append(f"drivetwin exited without printing 'stopped': {twin.stdout_lines}")
    assert not failures, failures


@pytest.fixture
def cmmp(launch) -> Twin:
    """One CMMP-AS, node 1, heartbeat 1000 ms commissioned."""
    return launch("cmmp-as", 1)


@pytest.fixture
def bench(launch) -> Twin:
    """One test bench node, node 1."""
    return launch("testbench", 1)


@pytest.fixture(scope="session")
def eds_files(tmp_path_factory) -> dict[str, Path]:
    """The EDS of each personality, as `drivetwin eds` prints it."""
    d = tmp_path_factory.mktemp("eds")
    files = {}
    for device in ("cmmp-as", "testbench", "nanotec-smci47s", "nanotec-pd4n", "kinco-fd3", "kinco-cd3"):
        r = run_cli("eds", "--device", device)
        assert r.returncode == 0, r.stderr
        path = d / f"{device}.eds"
        path.write_text(r.stdout)
        files[device] = path
    return files


@pytest.fixture
def connect():
    """Factory: connect(twin) -> canopen.Network joined to the twin's socketcand server."""
    import canopen

    networks = []

    def _connect(twin: Twin):
        net = canopen.Network()
        net.NOTIFIER_CYCLE = 0.05  # a short recv timeout: disconnect() joins the notifier thread
        net.connect(interface="socketcand", host=HOST, port=twin.port, channel=CHANNEL)
        networks.append(net)
        return net

    yield _connect
    for net in networks:
        try:
            net.disconnect()
        except Exception:
            pass


@pytest.fixture
def raw_bus():
    """Factory: raw_bus(twin) -> python-can Bus over socketcand (frames as they are on the wire)."""
    import can

    buses = []

    def _bus(twin: Twin):
        bus = can.Bus(interface="socketcand", host=HOST, port=twin.port, channel=CHANNEL)
        buses.append(bus)
        return bus

    yield _bus
    for bus in buses:
        try:
            bus.shutdown()
        except Exception:
            pass


def add_node(net, node_id: int, eds: Path):
    """net.add_node with the generous SDO response timeout."""
    node = net.add_node(node_id, str(eds))
    node.sdo.RESPONSE_TIMEOUT = SDO_TIMEOUT
    return node


@pytest.fixture
def node_of(connect, eds_files):
    """Factory: node_of(twin, node_id=None) -> canopen.RemoteNode with the twin's EDS."""

    def _node(twin: Twin, node_id: int | None = None, device: str | None = None):
        net = connect(twin)
        dev = device or twin.device
        # python-canopen's 0.3 s default is tight for a loaded 2-core CI machine; tests that
        # expect silence set their own
        return add_node(net, node_id if node_id is not None else twin.node, eds_files[dev])

    return _node


def recv_id(bus, can_id: int, timeout: float = 1.0):
    """The next frame with `can_id` on a raw python-can bus (others are skipped), or None."""
    deadline = time.monotonic() + timeout
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            return None
        msg = bus.recv(left)
        if msg is not None and msg.arbitration_id == can_id and not msg.is_error_frame:
            return msg


def sdo_request(bus, node: int, data: bytes, timeout: float = 2.0, expect: bool = True):
    """Send one SDO request frame (as given, any length) to `node`; return the response data."""
    import can

    bus.send(can.Message(arbitration_id=0x600 + node, data=data, is_extended_id=False))
    msg = recv_id(bus, 0x580 + node, timeout)
    if expect:
        assert msg is not None, f"no SDO response to {data.hex(' ')} within {timeout} s"
        return bytes(msg.data)
    return None if msg is None else bytes(msg.data)


def abort_frame(index: int, sub: int, code: int) -> bytes:
    return bytes([0x80, index & 0xFF, index >> 8, sub]) + code.to_bytes(4, "little")


class HeartbeatLog:
    """Every heartbeat / boot-up state byte python-canopen's NMT master sees for a node."""

    def __init__(self, node):
        self.states: list[tuple[float, int]] = []
        self.cond = threading.Condition()
        node.nmt.add_heartbeat_callback(self._on)

    def _on(self, state: int):
        with self.cond:
            self.states.append((time.monotonic(), state))
            self.cond.notify_all()

    def mark(self) -> int:
        with self.cond:
            return len(self.states)

    def wait_for(self, state: int, since: int, timeout: float) -> int:
        """Wait for a heartbeat with `state` after position `since`; returns the position just
        after it."""
        deadline = time.monotonic() + timeout
        with self.cond:
            while True:
                for i in range(since, len(self.states)):
                    if self.states[i][1] == state:
                        return i + 1
                left = deadline - time.monotonic()
                if left <= 0:
                    seen = [s for _, s in self.states[since:]]
                    pytest.fail(f"no heartbeat state 0x{state:02X} within {timeout} s; saw {seen}")
                self.cond.wait(left)

    def next_states(self, since: int, count: int, timeout: float) -> list[int]:
        """The states of the next `count` heartbeats after position `since`."""
        deadline = time.monotonic() + timeout
        with self.cond:
            while len(self.states) < since + count:
                left = deadline - time.monotonic()
                if left <= 0:
                    pytest.fail(f"only {len(self.states) - since} of {count} heartbeats in {timeout} s")
                self.cond.wait(left)
            return [s for _, s in self.states[since:since + count]]


def write_cell(path: Path, drives: list[tuple]) -> Path:
    """A cell TOML with the given (device, node, {"IIII:SS": value}[, [more lines]]) drives;
    the more lines are tables of the drive (`cmmp_switches`). The bus address in the file is a
    placeholder: --socketcand on the command line overrides it."""
    lines = ["[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', ""]
    for device, node, objects, *more in drives:
        lines += ["[[drive]]", f'device = "{device}"', f"node = {node}"]
        if objects:
            lines.append("[drive.objects]")
            lines += [f'"{key}" = {value}' for key, value in objects.items()]
        for extra in more:
            lines += extra
        lines.append("")
    path.write_text("\n".join(lines))
    return path


def map_pdo(pdo, objects: list[int], trans_type: int):
    """Maps `objects` into python-canopen's `pdo` with `trans_type`, enabled, and saves it to
    the node (SDO downloads of the communication and mapping parameters)."""
    pdo.clear()
    for index in objects:
        pdo.add_variable(index)
    pdo.trans_type = trans_type
    pdo.enabled = True
    pdo.save()
    return pdo


def cmmp_switches(node: int, kbit: int = 1000) -> list[str]:
    """`[drive.switches]` of a CMMP-AS M3 at `node` (its FCT base address, DIP1…5 OFF) and
    `kbit` (DIP6/DIP7, Tab. 2.4), CANopen on (DIP8): a CMMP-AS set to share a bus with drives
    at that rate (untouched it runs at 125 kbit/s; a Nanotec at 1 Mbit/s, a Kinco at 500)."""
    dips = {125: [], 250: [6], 500: [7], 1000: [6, 7]}[kbit] + [8]
    return ["[drive.switches]", 'variant = "m3"', f"base_address = {node}", f"on = {dips}"]


class RawClient:
    """A socketcand client written by hand on a plain TCP socket."""

    def __init__(self, port: int, timeout: float = 2.0):
        self.sock = socket.create_connection((HOST, port), timeout=timeout)
        self.buf = b""
        self.closed = False

    def send(self, data: bytes) -> bool:
        """False if the server has closed the connection."""
        try:
            self.sock.sendall(data)
            return True
        except OSError:
            self.closed = True
            return False

    def read_message(self, timeout: float = 2.0) -> str | None:
        """The next `< ... >` message, or None on close / timeout."""
        deadline = time.monotonic() + timeout
        while True:
            start = self.buf.find(b"<")
            end = self.buf.find(b">", start)
            if start >= 0 and end >= 0:
                msg = self.buf[start:end + 1].decode("ascii", "replace")
                self.buf = self.buf[end + 1:]
                return msg
            left = deadline - time.monotonic()
            if left <= 0 or self.closed:
                return None
            self.sock.settimeout(left)
            try:
                data = self.sock.recv(65536)
            except socket.timeout:
                return None
            except OSError:
                self.closed = True
                return None
            if not data:
                self.closed = True
                return None
            self.buf += data

    def reply(self, timeout: float = 2.0) -> str | None:
        """The next message that is not a `< frame ... >` (rawmode clients see all bus traffic),
        or None on close / timeout."""
        deadline = time.monotonic() + timeout
        while True:
            msg = self.read_message(max(0.0, deadline - time.monotonic()))
            if msg is None or not msg.startswith("< frame "):
                return msg
            if time.monotonic() > deadline:
                return None

    def expect(self, prefix: str, timeout: float = 2.0) -> str:
        """The next message that is not a frame must start with `prefix`."""
        msg = self.reply(timeout)
        assert msg is not None, f"expected {prefix!r}, connection closed or silent"
        assert msg.startswith(prefix), f"expected {prefix!r}, got {msg!r}"
        return msg

    def handshake(self, channel: str = CHANNEL):
        self.expect("< hi >")
        self.send(f"< open {channel} >".encode())
        self.expect("< ok >")
        self.send(b"< rawmode >")
        self.expect("< ok >")

    def close(self):
        try:
            self.sock.close()
        except OSError:
            pass


class Realtime:
    """The test process at SCHED_FIFO 20 while a cyclic master runs, as a real-time master
    would be (threads started meanwhile inherit it); restored afterwards. A no-op where
    real-time scheduling is not allowed."""

    def __enter__(self):
        self.old = None
        # A periodic sender thread (SYNC) must not wait the default 5 ms for the GIL.
        self.switch = sys.getswitchinterval()
        sys.setswitchinterval(0.0005)
        try:
            self.old = (os.sched_getscheduler(0), os.sched_getparam(0))
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(20))
        except (AttributeError, PermissionError, OSError):
            self.old = None
        return self

    def __exit__(self, *exc):
        sys.setswitchinterval(self.switch)
        if self.old is not None:
            os.sched_setscheduler(0, self.old[0], self.old[1])


def realtime_prefix() -> list[str]:
    """`chrt -f 20` where real-time scheduling is allowed: a twin that must keep a SYNC grid,
    as the real drive's firmware does, even on a loaded machine."""
    chrt = shutil.which("chrt")
    if chrt and subprocess.run([chrt, "-f", "20", "true"], capture_output=True).returncode == 0:
        return [chrt, "-f", "20"]
    return []


def ip(*args: str) -> subprocess.CompletedProcess:
    """`ip ARGS` (iproute2)."""
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=10)


def product_code(device: str = "cmmp-as") -> int:
    """The product code `drivetwin esi` writes (<Type ProductCode="#x0018C375" …>)."""
    out = run_cli("esi", "--device", device, check=True).stdout
    start = out.index('ProductCode="#x') + len('ProductCode="#x')
    return int(out[start:out.index('"', start)], 16)


def ip_steps(steps) -> None:
    """Runs `ip` with each step's arguments; skips the test at the first that fails."""
    for step in steps:
        r = ip(*step)
        if r.returncode != 0:
            pytest.skip(f"cannot create the veth pair (ip {' '.join(step)}): {r.stderr.strip()}")


@pytest.fixture
def veth():
    """A veth pair with one end in a private network namespace, for EtherCAT without
    hardware: (namespace, twin-side interface inside it, master-side interface here). Needs
    root and iproute2; skips with a message otherwise."""
    if os.geteuid() != 0:
        pytest.skip("EtherCAT over veth needs root (network namespace, raw sockets)")
    if shutil.which("ip") is None:
        pytest.skip("`ip` (iproute2) is not installed")
    tag = f"{os.getpid() % 100000}"
    ns, twin_if, master_if = f"dtw-ecat-{tag}", f"dtwA{tag}", f"dtwB{tag}"
    steps = [
        ("netns", "add", ns),
        ("link", "add", master_if, "type", "veth", "peer", "name", twin_if),
        ("link", "set", twin_if, "netns", ns),
        ("-n", ns, "link", "set", twin_if, "up"),
        ("link", "set", master_if, "up"),
    ]
    try:
        ip_steps(steps)
        yield ns, twin_if, master_if
    finally:
        ip("link", "del", master_if)  # deletes the peer too
        ip("netns", "del", ns)


def ecat_twin_start(veth, tmp_path, *extra: str, realtime: bool = False, slaves: int = 1):
    """Starts `drivetwin run --ethercat` in the `veth` namespace (`extra` arguments) and waits
    for its banner: (process, log file, banner lines). `ip netns exec` execs the twin, so the
    process is the twin itself (a signal to it reaches drivetwin)."""
    ns, twin_if, _ = veth
    log = (tmp_path / "drivetwin-ecat.log").open("w")
    prefix = realtime_prefix() if realtime else []
    proc = subprocess.Popen([*prefix, "ip", "netns", "exec", ns, str(DRIVETWIN_BIN), "run", "--ethercat", twin_if,
                             *extra],
                            stdout=subprocess.PIPE, stderr=log, text=True)
    lines = []
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line.strip())
        if line.startswith("running"):
            break
    if not (lines and lines[-1].startswith("running")):
        proc.kill()
        proc.wait()
        log.close()
        pytest.fail(f"drivetwin did not start: {lines} / {(tmp_path / 'drivetwin-ecat.log').read_text()}")
    assert any(f"EtherCAT on {twin_if}: {slaves} slave" in l for l in lines), lines
    return proc, log, lines


@contextlib.contextmanager
def ecat_twin_run(veth, tmp_path, *extra: str, realtime: bool = False, slaves: int = 1):
    """`drivetwin run --ethercat` in the `veth` namespace (`extra` arguments): (master-side
    interface, banner lines) while the block runs; stopped by SIGTERM and checked after it."""
    master_if = veth[2]
    proc, log, lines = ecat_twin_start(veth, tmp_path, *extra, realtime=realtime, slaves=slaves)
    try:
        yield master_if, lines
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                rest, _ = proc.communicate(timeout=STOP_TIMEOUT)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.communicate()
                pytest.fail("drivetwin did not stop on SIGTERM")
            assert "stopped" in rest, rest
            assert proc.returncode == 0, proc.returncode
        log.close()


LINKTYPE_CAN_SOCKETCAN = 227


def read_pcap(path):
    """[(seconds, can_id, flags, data)] from a pcap of LINKTYPE_CAN_SOCKETCAN, parsed by hand."""
    raw = path.read_bytes()
    assert len(raw) >= 24, "no pcap global header"
    magic = raw[:4]
    if magic in (b"\xd4\xc3\xb2\xa1", b"\x4d\x3c\xb2\xa1"):
        endian = "<"
    elif magic in (b"\xa1\xb2\xc3\xd4", b"\xa1\xb2\x3c\x4d"):
        endian = ">"
    else:
        pytest.fail(f"not a pcap file: magic {magic.hex()}")
    nanos = magic in (b"\x4d\x3c\xb2\xa1", b"\xa1\xb2\x3c\x4d")
    major, minor, _zone, _sigfigs, snaplen, linktype = struct.unpack(endian + "HHiIII", raw[4:24])
    assert (major, minor) == (2, 4)
    assert linktype == LINKTYPE_CAN_SOCKETCAN
    assert snaplen >= 16
    frames = []
    off = 24
    while off < len(raw):
        assert off + 16 <= len(raw), "torn record header"
        sec, frac, incl, orig = struct.unpack(endian + "IIII", raw[off:off + 16])
        off += 16
        assert incl == 16 and orig == 16, "a classic SocketCAN frame is 16 bytes"
        assert off + incl <= len(raw), "torn record"
        rec = raw[off:off + incl]
        off += incl
        can_id_flags, = struct.unpack(">I", rec[:4])  # SocketCAN header: CAN ID big-endian
        length = rec[4]
        assert length <= 8
        t = sec + frac / (1e9 if nanos else 1e6)
        frames.append((t, can_id_flags & 0x1FFFFFFF, can_id_flags & 0xE0000000, rec[8:8 + length]))
    return frames


def crc15(bits: list[int]) -> int:
    """CAN CRC-15 (polynomial 0x4599) over the bits from SOF to the end of the data."""
    crc = 0
    for b in bits:
        nxt = b ^ ((crc >> 14) & 1)
        crc = (crc << 1) & 0x7FFF
        if nxt:
            crc ^= 0x4599
    return crc


def frame_bits(can_id: int, data: bytes) -> int:
    """Bits of a standard data frame on the wire, SOF to the end of the intermission, with the
    stuff bits of SOF…CRC (ISO 11898-1)."""
    bits = [0]  # SOF
    bits += [(can_id >> i) & 1 for i in range(10, -1, -1)]
    bits += [0, 0, 0]  # RTR, IDE, r0
    bits += [(len(data) >> i) & 1 for i in range(3, -1, -1)]
    for byte in data:
        bits += [(byte >> i) & 1 for i in range(7, -1, -1)]
    crc = crc15(bits)
    bits += [(crc >> i) & 1 for i in range(14, -1, -1)]
    stuffed, run, last = 0, 0, None
    for b in bits:
        if b == last:
            run += 1
        else:
            run, last = 1, b
        if run == 5:
            stuffed += 1
            run, last = 1, 1 - b  # the stuff bit starts a run of its own
    return len(bits) + stuffed + 1 + 2 + 7 + 3  # CRC delimiter, ACK, EOF, intermission
