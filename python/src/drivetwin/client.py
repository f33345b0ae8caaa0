"""A typed client of the web console's REST API (its OpenAPI document: `GET /api/openapi.json`).

Standard library only (urllib, json). Each answer is a dataclass with the fields the API
documents; fields the client does not know yet are kept in `extra`, so a newer binary does not
break an older package. An error answer raises :class:`ApiError` (404: :class:`NotFound`, 409:
:class:`Conflict`) with the API's message, and for a refused SDO access its abort code and
the manual's reason.

A drive is named by its index in the cell (`GET /api/drives`: the CAN drives in cell-file
order, then the Modbus drives); an object by index and sub-index (numbers, or hex text).
"""

from __future__ import annotations

import dataclasses
import json
import socket
import time
import urllib.error
import urllib.parse
import urllib.request
from dataclasses import dataclass, field
from typing import Any, Dict, List, Mapping, Optional, Type, TypeVar, Union

from .errors import ApiError, ApiTimeout, Conflict, NotFound

#: The header that carries the write token (a console bound beyond loopback).
TOKEN_HEADER = "x-drivetwin-token"

T = TypeVar("T", bound="_View")

Index = Union[int, str]


class _View:
    """Built from the API's JSON: known fields by name, the rest in `extra`."""

    extra: Dict[str, Any]

    @classmethod
    def from_json(cls: Type[T], data: Mapping[str, Any]) -> T:
        names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
        known = {k: cls._convert(k, v) for k, v in data.items() if k in names and k != "extra"}
        view = cls(**known)  # type: ignore[call-arg]
        view.extra = {k: v for k, v in data.items() if k not in names}
        return view

    @classmethod
    def _convert(cls, name: str, value: Any) -> Any:
        return value


@dataclass
class StatusBit(_View):
    bit: int
    name: str
    set: bool
    word: Optional[str] = None
    extra: Dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class Drive(_View):
    """`GET /api/drives/N`: a drive of the cell and its statusword."""

    index: int
    device: str
    product: str
    vendor: str
    profile: str
    interface: str
    status_bits: List[StatusBit] = field(default_factory=list)
    node: Optional[int] = None
    state: Optional[str] = None
    statusword: Optional[int] = None
    display: Optional[str] = None
    extra: Dict[str, Any] = field(default_factory=dict, repr=False)

    @classmethod
    def _convert(cls, name: str, value: Any) -> Any:
        if name == "status_bits":
            return [StatusBit.from_json(b) for b in value]
        return value


@dataclass
class Object(_View):
    """`GET /api/drives/N/objects/I/S`: an object dictionary entry and its value."""

    index: str
    sub: int
    name: str
    object: str
    type: str
    access: str
    unit: str
    pdo_mappable: bool
    value: Optional[str] = None
    raw: Optional[str] = None
    min: Optional[float] = None
    max: Optional[float] = None
    read_error: Optional[str] = None
    extra: Dict[str, Any] = field(default_factory=dict, repr=False)

    @property
    def number(self) -> Union[int, float]:
        """The value as a number (integers as int)."""
        if self.value is None:
            raise ValueError(f"{self.index}:{self.sub} has no value: {self.read_error}")
        try:
            return int(self.value, 0)
        except ValueError:
            return float(self.value)

    @property
    def bytes(self) -> bytes:
        return bytes.fromhex(self.raw or "")


@dataclass
class Plant(_View):
    """`GET /api/drives/N/plant`: the simulated motor and axis."""

    at_s: float
    kind: str
    position: Optional[float] = None
    velocity: Optional[float] = None
    current: Optional[float] = None
    digital_inputs: Optional[int] = None
    load_torque_nm: Optional[float] = None
    display: Optional[str] = None
    extra: Dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class Sample(_View):
    t: float
    position: Optional[float] = None
    velocity: Optional[float] = None
    current: Optional[float] = None
    objects: Dict[str, float] = field(default_factory=dict)
    extra: Dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class Physics(_View):
    """`GET /api/drives/N/physics`: temperatures and the encoder."""

    ambient_c: float
    motor_temperature_c: float
    power_stage_temperature_c: float
    encoder: str
    noise_increments: Optional[int] = None
    extra: Dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class Diagnostic(_View):
    """A diagnostic message of the drive's manual, raised or not."""

    number: str
    register: int
    reaction: str
    text: str
    source: str
    active: bool
    code: Optional[str] = None
    emcy: Optional[str] = None
    display: Optional[str] = None
    classes: Optional[str] = None
    reactions: Optional[str] = None
    extra: Dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class ErrorEntry(_View):
    code: str
    text: str
    time_ms: Optional[int] = None
    event: Optional[str] = None
    extra: Dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class Motion(_View):
    """`GET /api/drives/N/motion`: state, status word, active error and error history."""

    drive: int
    profile: str
    state: str
    word: int
    bits: List[StatusBit] = field(default_factory=list)
    history: List[ErrorEntry] = field(default_factory=list)
    active_error: Optional[ErrorEntry] = None
    display: Optional[str] = None
    device_control: Optional[str] = None
    extra: Dict[str, Any] = field(default_factory=dict, repr=False)

    @classmethod
    def _convert(cls, name: str, value: Any) -> Any:
        if name == "bits":
            return [StatusBit.from_json(b) for b in value]
        if name == "history":
            return [ErrorEntry.from_json(e) for e in value]
        if name == "active_error" and value is not None:
            return ErrorEntry.from_json(value)
        return value


@dataclass
class Bus(_View):
    """`GET /api/buses`: a CAN bus, its load and its nodes' error states."""

    index: int
    drives: int
    node_errors: List[Dict[str, Any]] = field(default_factory=list)
    bitrate: Optional[int] = None
    load_percent: Optional[float] = None
    frames: Optional[int] = None
    late: Optional[int] = None
    dropped: Optional[int] = None
    longest_wait_us: Optional[int] = None
    extra: Dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class Fault(_View):
    """A wire fault in force on a front end (`/api/wire/{front}/{index}/faults`)."""

    id: int
    fault: str
    reach: str
    node: Optional[int] = None
    cob_id: Optional[int] = None
    delay_ms: Optional[float] = None
    share: Optional[float] = None
    frames_left: Optional[int] = None
    until_s: Optional[float] = None
    extra: Dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class Trace(_View):
    """A pcap / candump trace of a bus being written."""

    bus: int
    path: str
    extra: Dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class Outcome(_View):
    name: str
    passed: bool
    detail: str
    extra: Dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class Report(_View):
    """A scenario's report: each expectation met or not."""

    scenario: str
    passed: bool
    expectations: List[Outcome] = field(default_factory=list)
    errors: List[str] = field(default_factory=list)
    frames: int = 0
    extra: Dict[str, Any] = field(default_factory=dict, repr=False)

    @classmethod
    def _convert(cls, name: str, value: Any) -> Any:
        if name == "expectations":
            return [Outcome.from_json(o) for o in value]
        return value


@dataclass
class ScenarioRun(_View):
    """A scenario started on the live cell: running, or done with its report."""

    id: int
    name: str
    status: str
    length_s: float
    report: Optional[Report] = None
    error: Optional[str] = None
    extra: Dict[str, Any] = field(default_factory=dict, repr=False)

    @classmethod
    def _convert(cls, name: str, value: Any) -> Any:
        if name == "report" and value is not None:
            return Report.from_json(value)
        return value

    @property
    def done(self) -> bool:
        return self.status == "done"


def _hex(value: Index, width: int) -> str:
    if isinstance(value, int):
        return f"{value:0{width}X}"
    return str(value)


class Client:
    """The REST API of one cell's web console (`Cell.api`, or `Client("http://host:port/")`)."""

    def __init__(self, base_url: str, token: Optional[str] = None, timeout: float = 10.0):
        self.base_url = base_url if base_url.endswith("/") else base_url + "/"
        self.token = token
        self.timeout = timeout

    # -- transport -----------------------------------------------------------------------

    def request(self, method: str, path: str, body: Any = None, *,
                text: Optional[str] = None) -> Any:
        """One request; the decoded JSON answer (None for an empty one)."""
        url = urllib.parse.urljoin(self.base_url, path.lstrip("/"))
        headers = {"Accept": "application/json"}
        data = None
        if text is not None:
            data = text.encode()
            headers["Content-Type"] = "text/plain; charset=utf-8"
        elif body is not None:
            data = json.dumps(body).encode()
            headers["Content-Type"] = "application/json"
        if self.token:
            headers[TOKEN_HEADER] = self.token
        req = urllib.request.Request(url, data=data, method=method, headers=headers)
        try:
            with urllib.request.urlopen(req, timeout=self.timeout) as resp:
                payload = resp.read()
        except urllib.error.HTTPError as e:
            raw = e.read()
            try:
                decoded: Any = json.loads(raw)
            except ValueError:
                decoded = raw.decode(errors="replace")
            kind = {404: NotFound, 409: Conflict}.get(e.code, ApiError)
            raise kind(e.code, method, path, decoded) from None
        except (socket.timeout, TimeoutError) as e:
            raise ApiTimeout(f"{method} {path}: no answer within {self.timeout} s") from e
        except urllib.error.URLError as e:
            if isinstance(e.reason, (socket.timeout, TimeoutError)):
                raise ApiTimeout(f"{method} {path}: no answer within {self.timeout} s") from e
            raise
        if not payload:
            return None
        return json.loads(payload)

    def openapi(self) -> Dict[str, Any]:
        """The OpenAPI document of the console."""
        return self.request("GET", "api/openapi.json")

    # -- drives --------------------------------------------------------------------------

    def drives(self) -> List[Drive]:
        return [Drive.from_json(d) for d in self.request("GET", "api/drives")]

    def drive(self, drive: int) -> Drive:
        return Drive.from_json(self.request("GET", f"api/drives/{drive}"))

    def enable(self, drive: int) -> Drive:
        """Steps the CiA 402 controlword to OPERATION ENABLED (a fault reset first); a drive
        that does not get there raises :class:`Conflict` with its reason."""
        return Drive.from_json(self.request("POST", f"api/drives/{drive}/enable"))

    def disable(self, drive: int) -> Drive:
        return Drive.from_json(self.request("POST", f"api/drives/{drive}/disable"))

    # -- objects -------------------------------------------------------------------------

    def objects(self, drive: int) -> List[Object]:
        """Every entry of the drive's dictionary with its value."""
        return [Object.from_json(o) for o in self.request("GET", f"api/drives/{drive}/objects")]

    def read(self, drive: int, index: Index, sub: Index = 0) -> Object:
        """One entry, read as a master would (refusals raise :class:`Conflict`)."""
        return Object.from_json(self.request(
            "GET", f"api/drives/{drive}/objects/{_hex(index, 4)}/{_hex(sub, 2)}"))

    def write(self, drive: int, index: Index, sub: Index, value: Union[int, float, str]) -> Object:
        """Writes a value in the entry's type (a number, or text as `0x1F`, `1.5`, a string)."""
        return Object.from_json(self.request(
            "PUT", f"api/drives/{drive}/objects/{_hex(index, 4)}/{_hex(sub, 2)}",
            {"value": str(value)}))

    def write_raw(self, drive: int, index: Index, sub: Index, raw: bytes) -> Object:
        """Writes the bytes as they are (little-endian)."""
        return Object.from_json(self.request(
            "PUT", f"api/drives/{drive}/objects/{_hex(index, 4)}/{_hex(sub, 2)}",
            {"raw": raw.hex().upper()}))

    # -- plant ---------------------------------------------------------------------------

    def plant(self, drive: int) -> Plant:
        return Plant.from_json(self.request("GET", f"api/drives/{drive}/plant"))

    def sample(self, drive: int) -> Sample:
        """The latest plant sample (the console's scope streams them over a WebSocket)."""
        batch = self.request("GET", f"api/drives/{drive}/samples")
        return Sample.from_json(batch["samples"][-1])

    def set_inputs(self, drive: int, mask: int, levels: int) -> Plant:
        """Forces the digital inputs in `mask` to `levels` (60FDh as the drive shows it)."""
        return Plant.from_json(self.request("PUT", f"api/drives/{drive}/inputs",
                                            {"mask": mask, "levels": levels}))

    def set_load(self, drive: int, torque_nm: float) -> Plant:
        return Plant.from_json(self.request("PUT", f"api/drives/{drive}/load",
                                            {"torque_nm": torque_nm}))

    def set_supply(self, drive: int, volts: Optional[float]) -> Plant:
        """The supply voltage; None: the device file's nominal voltage."""
        return Plant.from_json(self.request("PUT", f"api/drives/{drive}/supply",
                                            {"volts": volts}))

    def physics(self, drive: int) -> Physics:
        return Physics.from_json(self.request("GET", f"api/drives/{drive}/physics"))

    def set_ambient(self, drive: int, celsius: float) -> Physics:
        return Physics.from_json(self.request("PUT", f"api/drives/{drive}/ambient",
                                              {"celsius": celsius}))

    def set_thermal(self, drive: int, **params: float) -> Physics:
        """`motor_rise_k`, `motor_time_constant_s`, `stage_rise_k`, `stage_time_constant_s`."""
        return Physics.from_json(self.request("PUT", f"api/drives/{drive}/thermal", params))

    def set_encoder(self, drive: int, fault: str,
                    noise_increments: Optional[int] = None) -> Physics:
        """`connected`, `disconnected` or `noisy` (± `noise_increments`)."""
        body: Dict[str, Any] = {"fault": fault}
        if noise_increments is not None:
            body["noise_increments"] = noise_increments
        return Physics.from_json(self.request("PUT", f"api/drives/{drive}/encoder", body))

    def set_switch(self, drive: int, name: str, actuated: Optional[bool]) -> Physics:
        """A limit or home switch by name (`limit_positive`, …); None: back to the travel."""
        return Physics.from_json(self.request(
            "PUT", f"api/drives/{drive}/switches/{urllib.parse.quote(name)}",
            {"actuated": actuated}))

    # -- motion (the console's enable / jog / move / home) -------------------------------

    def motion(self, drive: int) -> Motion:
        return Motion.from_json(self.request("GET", f"api/drives/{drive}/motion"))

    def motion_enable(self, drive: int) -> Motion:
        return Motion.from_json(self.request("POST", f"api/drives/{drive}/motion/enable"))

    def motion_disable(self, drive: int) -> Motion:
        return Motion.from_json(self.request("POST", f"api/drives/{drive}/motion/disable"))

    def home(self, drive: int) -> Motion:
        return Motion.from_json(self.request("POST", f"api/drives/{drive}/motion/home"))

    def jog(self, drive: int, direction: int, velocity: Optional[int] = None) -> Motion:
        body: Dict[str, Any] = {"direction": direction}
        if velocity is not None:
            body["velocity"] = velocity
        return Motion.from_json(self.request("POST", f"api/drives/{drive}/motion/jog", body))

    def move(self, drive: int, target: int, relative: bool = False,
             velocity_percent: Optional[int] = None) -> Motion:
        body: Dict[str, Any] = {"target": target, "relative": relative}
        if velocity_percent is not None:
            body["velocity_percent"] = velocity_percent
        return Motion.from_json(self.request("POST", f"api/drives/{drive}/motion/move", body))

    # -- diagnostics ---------------------------------------------------------------------

    def diagnostics(self, drive: int) -> List[Diagnostic]:
        """Every diagnostic message of the drive's manual, `active` where raised."""
        return [Diagnostic.from_json(d)
                for d in self.request("GET", f"api/drives/{drive}/diagnostics")]

    def raise_diagnostic(self, drive: int, number: str) -> Diagnostic:
        """Raises a message by its number as the manual prints it (`08-2`, `2Fh`, …)."""
        return Diagnostic.from_json(self.request(
            "POST", f"api/drives/{drive}/diagnostics/{urllib.parse.quote(number)}"))

    def clear_diagnostic(self, drive: int, number: str) -> Diagnostic:
        return Diagnostic.from_json(self.request(
            "DELETE", f"api/drives/{drive}/diagnostics/{urllib.parse.quote(number)}"))

    # -- buses and wire faults -----------------------------------------------------------

    def buses(self) -> List[Bus]:
        return [Bus.from_json(b) for b in self.request("GET", "api/buses")]

    def disturb(self, bus: int, node: int, frames: int) -> Bus:
        """The node's next `frames` transmissions fail (16: error passive, 32: bus off)."""
        return Bus.from_json(self.request("POST", f"api/buses/{bus}/disturb",
                                          {"node": node, "frames": frames}))

    def faults(self, front: str = "bus", index: int = 0) -> List[Fault]:
        """The wire faults in force on a front end: `bus`, `modbus`, `ethercat` or `client`."""
        return [Fault.from_json(f)
                for f in self.request("GET", f"api/wire/{front}/{index}/faults")]

    def add_fault(self, fault: str, front: str = "bus", index: int = 0,
                  **spec: Any) -> Fault:
        """Starts a fault (`drop`, `delay`, `corrupt`, `cable-break`, `stop-sync`) with the
        API's keys: `node`, `reach`, `cob_id`, `delay`, `share`, `frames`, `for_` (`for`)."""
        body = {("for" if k == "for_" else k): v for k, v in spec.items()}
        body["fault"] = fault
        return Fault.from_json(self.request("POST", f"api/wire/{front}/{index}/faults", body))

    def clear_faults(self, front: str = "bus", index: int = 0) -> List[Fault]:
        return [Fault.from_json(f)
                for f in self.request("DELETE", f"api/wire/{front}/{index}/faults")]

    def remove_fault(self, fault_id: int, front: str = "bus", index: int = 0) -> List[Fault]:
        return [Fault.from_json(f) for f in
                self.request("DELETE", f"api/wire/{front}/{index}/faults/{fault_id}")]

    # -- traces --------------------------------------------------------------------------

    def start_trace(self, bus: int = 0, name: Optional[str] = None) -> Trace:
        """Starts a trace of every frame of the bus (`name`: `*.pcap` or `*.log`, made in the
        system's temporary folder); its `path` is complete after :meth:`stop_trace`."""
        return Trace.from_json(self.request("POST", f"api/buses/{bus}/trace", {"name": name}))

    def stop_trace(self, bus: int = 0) -> None:
        self.request("DELETE", f"api/buses/{bus}/trace")

    # -- scenarios -----------------------------------------------------------------------

    def start_scenario(self, toml_text: str) -> ScenarioRun:
        """Starts a scenario (a scenario file's TOML) on the live cell."""
        return ScenarioRun.from_json(self.request("POST", "api/scenarios", text=toml_text))

    def scenario(self, run_id: int) -> ScenarioRun:
        return ScenarioRun.from_json(self.request("GET", f"api/scenarios/{run_id}"))

    def scenarios(self) -> List[ScenarioRun]:
        return [ScenarioRun.from_json(r) for r in self.request("GET", "api/scenarios")]

    def run_scenario(self, toml_text: str, timeout: Optional[float] = None,
                     interval: float = 0.1) -> Report:
        """Starts a scenario and waits for its report (default wait: its length + 10 s)."""
        run = self.start_scenario(toml_text)
        if run.error:
            raise ApiError(400, "POST", "api/scenarios", {"error": run.error})
        deadline = time.monotonic() + (timeout if timeout is not None else run.length_s + 10.0)
        while not run.done:
            if time.monotonic() > deadline:
                raise ApiTimeout(f"scenario {run.name!r} (run {run.id}) still running")
            time.sleep(interval)
            run = self.scenario(run.id)
        if run.report is None:
            raise ApiError(500, "GET", f"api/scenarios/{run.id}",
                           {"error": run.error or "done without a report"})
        return run.report


__all__ = ["Bus", "Client", "Diagnostic", "Drive", "ErrorEntry", "Fault", "Motion", "Object",
           "Outcome", "Physics", "Plant", "Report", "Sample", "ScenarioRun", "StatusBit",
           "TOKEN_HEADER", "Trace"]
