"""A running cell: `drivetwin run` on free loopback ports, as a context manager.

The binary binds every server to the port it is given (port 0: any free one) and prints the
address it got, one line each, then `running; Ctrl-C stops` once every socket is bound; it
stops on SIGTERM and prints `stopped`. The cell reads those lines: no port is guessed, no
sleep waits for a start.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Union

from . import cellfile
from .binary import find_binary
from .client import Client
from .errors import CellDied, CellStartError

#: What the binary prints once every socket is bound and the loop runs.
READY_LINE = "running; Ctrl-C stops"
#: What it prints after a clean stop.
STOPPED_LINE = "stopped"

_SOCKETCAND = re.compile(r"^socketcand server on (?P<host>[^ ]+):(?P<port>\d+), channel (?P<channel>\S+)$")
_MODBUS = re.compile(r"^modbus server on (?P<host>[^ ]+):(?P<port>\d+)$")
_HTTP = re.compile(r"^web console on (?P<url>http://[^/ ]+/)(\?token=(?P<token>\S+))?$")
_CI = re.compile(r"^CI terminal of drive (?P<drive>\d+) on (?P<host>[^ ]+):(?P<port>\d+)$")
_SERIAL = re.compile(r"^(?P<kind>RS232|RS485) line on (?P<path>.+?)( \(pty (?P<pty>[^)]+)\))?$")


@dataclass(frozen=True)
class Endpoint:
    """A TCP address a server of the cell listens on."""

    host: str
    port: int

    def __str__(self) -> str:
        return f"{self.host}:{self.port}"


@dataclass(frozen=True)
class SocketcandBus:
    """A CAN bus of the cell, served over socketcand (python-can's `socketcand` interface)."""

    host: str
    port: int
    channel: str

    def can_kwargs(self) -> Dict[str, Any]:
        """Keyword arguments for `can.Bus(...)` and `canopen.Network().connect(...)`."""
        return {"interface": "socketcand", "host": self.host, "port": self.port,
                "channel": self.channel}

    def __str__(self) -> str:
        return f"{self.host}:{self.port} ({self.channel})"


@dataclass(frozen=True)
class SerialLine:
    """A drive's serial port: `path` is the link pyserial opens (to the twin's pty)."""

    kind: str  # "rs232" or "rs485"
    path: str
    pty: Optional[str]


class Cell:
    """A `drivetwin run` process with its servers on free loopback ports.

    ``Cell()`` is one CMMP-AS at node 1 (as ``drivetwin run``); ``Cell(devices=["cmmp-as",
    "cmmo-st"])`` a cell of those drives (CAN drives numbered 1, 2, …, each CMMO-ST on a Modbus
    server of its own); ``Cell(config=path_or_toml_text)`` a cell file, its addresses moved to
    free ports. Use it as a context manager::

        with drivetwin.Cell(devices=["cmmp-as", "cmmo-st"]) as cell:
            net.connect(**cell.bus.can_kwargs())
            ModbusTcpClient(cell.modbus[0].host, port=cell.modbus[0].port)
            cell.api.drives()

    Leaving the block stops the process with SIGTERM; if it had died, or does not stop
    cleanly, :class:`CellDied` is raised with its standard error.
    """

    def __init__(self, config: Union[str, os.PathLike, None] = None, *,
                 devices: Optional[Sequence[cellfile.DeviceSpec]] = None,
                 bitrate: Union[int, str, None] = None, channel: str = "vcan0",
                 http: bool = True, state_dir: Union[str, os.PathLike, None] = None,
                 args: Sequence[str] = (), binary: Union[str, os.PathLike, None] = None,
                 start_timeout: float = 20.0, stop_timeout: float = 10.0):
        if config is not None and devices is not None:
            raise ValueError("Cell: give a config or devices, not both")
        self._config = config
        self._devices = list(devices) if devices is not None else None
        self._bitrate = bitrate
        self._channel = channel
        self._http = http
        self._state_dir = Path(state_dir) if state_dir is not None else None
        self._extra = list(args)
        self._binary = binary
        self.start_timeout = start_timeout
        self.stop_timeout = stop_timeout
        self._tmp: Optional[tempfile.TemporaryDirectory] = None
        self._proc: Optional[subprocess.Popen] = None
        self._reader: Optional[threading.Thread] = None
        self._ready = threading.Event()
        self._stderr_path: Optional[Path] = None
        self._client: Optional[Client] = None
        #: The `[[drive]]` tables of the cell file it runs (as the binary got them).
        self.drive_specs: List[Dict[str, Any]] = []
        #: Every line the process printed on its standard output so far.
        self.stdout_lines: List[str] = []
        #: The CAN buses served over socketcand, in the cell file's order.
        self.buses: List[SocketcandBus] = []
        #: The Modbus TCP servers (CMMO-ST), in the cell file's order of the drives.
        self.modbus: List[Endpoint] = []
        #: The serial lines (links to ptys), in the order the drives list them.
        self.serial: List[SerialLine] = []
        #: The CI terminals by drive number (1 = first drive of the cell file).
        self.ci_terminals: Dict[int, Endpoint] = {}
        #: The web console's base URL (`http://127.0.0.1:PORT/`), none with `http=False`.
        self.http: Optional[str] = None
        self.token: Optional[str] = None

    # -- the process ---------------------------------------------------------------------

    @property
    def workdir(self) -> Path:
        """A temporary folder of the cell (its cell file, pty links, state, EDS files)."""
        if self._tmp is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="drivetwin-")
        return Path(self._tmp.name)

    def command(self) -> List[str]:
        """The command line the cell runs (writes its cell file into `workdir`)."""
        binary = str(find_binary(self._binary))
        state_dir = self._state_dir or (self.workdir / "state")
        state_dir.mkdir(parents=True, exist_ok=True)
        args = [binary, "run", "--state-dir", str(state_dir)]
        serial_dir = self.workdir / "serial"
        serial_dir.mkdir(exist_ok=True)
        if self._config is not None:
            doc, base = cellfile.read_config(self._config)
            doc = cellfile.to_free_ports(doc, serial_dir, base)
        else:
            devices = self._devices if self._devices is not None else ["cmmp-as"]
            doc = cellfile.from_devices(devices, bitrate=self._bitrate, channel=self._channel,
                                        serial_dir=serial_dir)
        self.drive_specs = [dict(d) for d in doc.get("drive", [])]
        path = self.workdir / "cell.toml"
        path.write_text(cellfile.dumps(doc))
        args += ["--config", str(path)]
        if self._bitrate is not None and self._config is not None:
            args += ["--bitrate", str(self._bitrate)]
        args += ["--http", "127.0.0.1:0" if self._http else "off"]
        return args + self._extra

    def start(self) -> "Cell":
        """Starts the process and returns once it prints that it runs (every server bound)."""
        if self.running:
            raise RuntimeError("the cell is running already")
        cmd = self.command()
        self._stderr_path = self.workdir / "stderr.txt"
        self.stdout_lines = []
        self._ready = threading.Event()
        with open(self._stderr_path, "wb") as err:
            self._proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=err,
                                          stdin=subprocess.DEVNULL, text=True, bufsize=1)
        self._reader = threading.Thread(target=self._read_stdout, args=(self._proc,),
                                        name="drivetwin-stdout", daemon=True)
        self._reader.start()
        self._ready.wait(self.start_timeout)
        if READY_LINE not in self.stdout_lines or self._proc.poll() is not None:
            try:
                # The output ended: the process is ending (or has).
                self._proc.wait(5 if self._ready.is_set() else 0)
                why = f"exited with {self._proc.returncode} before it ran"
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
                why = f"did not say {READY_LINE!r} within {self.start_timeout} s"
            self._join_reader()
            raise CellStartError(f"drivetwin run {why}: {' '.join(cmd)}", self.stderr,
                                 "\n".join(self.stdout_lines))
        self._parse_addresses()
        return self

    def _read_stdout(self, proc: subprocess.Popen) -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            line = line.rstrip("\n")
            self.stdout_lines.append(line)
            if line == READY_LINE:
                self._ready.set()
        self._ready.set()  # end of output: start() looks at the exit code

    def _join_reader(self) -> None:
        if self._reader is not None:
            self._reader.join(5)

    def _parse_addresses(self) -> None:
        self.buses, self.modbus, self.serial, self.ci_terminals = [], [], [], {}
        self.http = self.token = None
        for line in list(self.stdout_lines):
            if m := _SOCKETCAND.match(line):
                self.buses.append(SocketcandBus(m["host"], int(m["port"]), m["channel"]))
            elif m := _MODBUS.match(line):
                self.modbus.append(Endpoint(m["host"], int(m["port"])))
            elif m := _HTTP.match(line):
                self.http, self.token = m["url"], m["token"]
            elif m := _CI.match(line):
                self.ci_terminals[int(m["drive"])] = Endpoint(m["host"], int(m["port"]))
            elif m := _SERIAL.match(line):
                self.serial.append(SerialLine(m["kind"].lower(), m["path"], m["pty"]))
        self._client = None

    @property
    def running(self) -> bool:
        return self._proc is not None and self._proc.poll() is None

    @property
    def pid(self) -> Optional[int]:
        return self._proc.pid if self._proc is not None else None

    @property
    def stderr(self) -> str:
        """What the process wrote on its standard error (its log) so far."""
        if self._stderr_path is None:
            return ""
        try:
            return self._stderr_path.read_text(errors="replace")
        except OSError:
            return ""

    def check(self) -> None:
        """Raises :class:`CellDied` if the process has ended."""
        if self._proc is not None and self._proc.poll() is not None:
            raise CellDied(f"drivetwin run ended with exit code {self._proc.returncode}",
                           self._proc.returncode, self.stderr)

    def stop(self) -> int:
        """SIGTERM, then waits for a clean stop (exit code 0 and `stopped`); returns the exit
        code. Raises :class:`CellDied` if the process had died, ignored SIGTERM or failed."""
        proc = self._proc
        if proc is None:
            return 0
        died = proc.poll() is not None
        killed = False
        if not died:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(self.stop_timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
                killed = True
        self._join_reader()
        self._proc = None
        code = proc.returncode
        if died:
            raise CellDied(f"drivetwin run had ended (exit code {code}) before the cell was "
                           "stopped", code, self.stderr)
        if killed:
            raise CellDied(f"drivetwin run ignored SIGTERM for {self.stop_timeout} s and was "
                           "killed", code, self.stderr)
        if code != 0 or STOPPED_LINE not in self.stdout_lines:
            raise CellDied(f"drivetwin run did not stop cleanly (exit code {code})", code,
                           self.stderr)
        return code

    def close(self) -> None:
        """Stops the process if it runs (no check) and removes the temporary folder."""
        if self._proc is not None and self._proc.poll() is None:
            self._proc.kill()
            self._proc.wait()
        self._proc = None
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    def __enter__(self) -> "Cell":
        try:
            return self.start()
        except BaseException:
            self.close()
            raise

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc_type is None:
                self.stop()
            else:
                # The block's own exception is the news; a cell that died says why beside it.
                try:
                    self.stop()
                except CellDied as died:
                    if hasattr(exc, "add_note"):
                        exc.add_note(str(died))
        finally:
            self.close()

    # -- what it serves ------------------------------------------------------------------

    @property
    def bus(self) -> SocketcandBus:
        """The first CAN bus (the one `canopen` / `python-can` clients usually join)."""
        if not self.buses:
            raise LookupError("the cell has no CAN bus served over socketcand")
        return self.buses[0]

    @property
    def api(self) -> Client:
        """The REST client of the cell's web console."""
        if self.http is None:
            raise LookupError("the cell runs without its web console (http=False)")
        if self._client is None:
            self._client = Client(self.http, token=self.token)
        return self._client

    def eds(self, device: str = "cmmp-as") -> Path:
        """The EDS of a personality (`drivetwin eds`), written into `workdir` once."""
        path = self.workdir / f"{device}.eds"
        if not path.exists():
            out = subprocess.run([str(find_binary(self._binary)), "eds", "--device", device,
                                  "--output", str(path)], capture_output=True, text=True,
                                 timeout=60)
            if out.returncode != 0:
                raise CellStartError(f"drivetwin eds --device {device} failed", out.stderr)
        return path

    def wait_until(self, predicate, timeout: float = 5.0, interval: float = 0.02,
                   what: str = "the condition") -> Any:
        """Polls `predicate` until it returns something truthy (that value); raises
        TimeoutError after `timeout` s, and :class:`CellDied` at once if the cell ends."""
        deadline = time.monotonic() + timeout
        while True:
            value = predicate()
            if value:
                return value
            self.check()
            if time.monotonic() > deadline:
                raise TimeoutError(f"timed out after {timeout} s waiting for {what}")
            time.sleep(interval)

    def __repr__(self) -> str:
        state = "running" if self.running else "stopped"
        return f"<drivetwin.Cell {state} buses={self.buses} modbus={self.modbus} http={self.http}>"


__all__ = ["Cell", "Endpoint", "SerialLine", "SocketcandBus", "READY_LINE"]
