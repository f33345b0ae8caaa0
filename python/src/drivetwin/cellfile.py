"""Cell files (TOML) made from a list of devices, or taken from a user's file with every
listening address moved to a free loopback port.

The standard library reads TOML (tomllib, Python 3.11) but does not write it; cell files use
tables, arrays of tables, strings, numbers, booleans and arrays, which `dumps` writes.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

try:
    import tomllib  # type: ignore[import-not-found]
except ModuleNotFoundError:  # Python < 3.11
    import tomli as tomllib  # type: ignore[no-redef]

#: Any free loopback port: the binary binds it and prints the address it got.
ANY_PORT = "127.0.0.1:0"

#: A device in `Cell(devices=[...])`: a personality's name, or a `[[drive]]` table as a dict.
DeviceSpec = Union[str, Mapping[str, Any]]

#: The personalities served over Modbus TCP (FHPP), not on CAN.
MODBUS_DEVICES = frozenset({"cmmo-st"})

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def loads(text: str) -> Dict[str, Any]:
    return tomllib.loads(text)


def _key(k: str) -> str:
    return k if _BARE_KEY.match(k) else _string(k)


def _string(s: str) -> str:
    out = ['"']
    for ch in s:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ch == "\n":
            out.append("\\n")
        elif ch == "\t":
            out.append("\\t")
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return _string(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, Mapping):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {type(v).__name__} {v!r} to a cell file")


def _is_table_array(v: Any) -> bool:
    return isinstance(v, (list, tuple)) and len(v) > 0 and all(isinstance(x, Mapping) for x in v)


def _table(lines: List[str], path: List[str], table: Mapping[str, Any]) -> None:
    # Plain keys first: they belong to the table above any sub-table header.
    for k, v in table.items():
        if not isinstance(v, Mapping) and not _is_table_array(v):
            lines.append(f"{_key(k)} = {_value(v)}")
    for k, v in table.items():
        sub = path + [_key(k)]
        if isinstance(v, Mapping):
            lines.append("")
            lines.append("[" + ".".join(sub) + "]")
            _table(lines, sub, v)
        elif _is_table_array(v):
            for item in v:
                lines.append("")
                lines.append("[[" + ".".join(sub) + "]]")
                _table(lines, sub, item)


def dumps(doc: Mapping[str, Any]) -> str:
    """`doc` as TOML text (tables as `[a.b]` headers, lists of tables as `[[a]]`)."""
    lines: List[str] = []
    _table(lines, [], doc)
    return "\n".join(lines).lstrip("\n") + "\n"


def from_devices(devices: Sequence[DeviceSpec], *, bitrate: Union[int, str, None],
                 channel: str, serial_dir: Path) -> Dict[str, Any]:
    """A cell file of `devices` on one CAN bus with a socketcand server on a free port.

    CANopen drives without a `node` are numbered 1, 2, … in order and get the heartbeat
    (1017h = 1000 ms) that `drivetwin run --device` commissions, and the CMMP-AS its CiA 402
    FAULT statusword (6510h:F0 = 0080h), so that python-canopen's `wait_for_heartbeat` and
    BaseNode402 work as with the default cell. A CMMO-ST gets a Modbus server on a free port;
    `rs232 = true` / `rs485 = true` a pty link in `serial_dir`; `ci_terminal = true` a free port.
    """
    bus: Dict[str, Any] = {"socketcand": ANY_PORT, "channel": channel}
    if bitrate is not None:
        bus["bitrate"] = bitrate
    drives: List[Dict[str, Any]] = []
    used_nodes = {int(d["node"]) for d in devices if isinstance(d, Mapping) and "node" in d}
    next_node = 1
    for i, spec in enumerate(devices):
        drive: Dict[str, Any] = {"device": spec} if isinstance(spec, str) else dict(spec)
        if "device" not in drive and "eds" not in drive:
            raise ValueError(f"devices[{i}]: a drive needs a `device` (or an `eds`): {spec!r}")
        device = str(drive.get("device", ""))
        if device in MODBUS_DEVICES:
            if drive.get("modbus", True) is True:
                drive["modbus"] = ANY_PORT
        else:
            if "node" not in drive:
                while next_node in used_nodes:
                    next_node += 1
                drive["node"] = next_node
                used_nodes.add(next_node)
            objects = dict(drive.get("objects", {}))
            objects.setdefault("1017:00", 1000)
            if device == "cmmp-as":
                objects.setdefault("6510:F0", 0x0080)
            drive["objects"] = objects
        for port in ("rs232", "rs485", "ci_terminal"):
            if drive.get(port) is False:
                del drive[port]
        for port in ("rs232", "rs485"):
            if drive.get(port) is True:
                drive[port] = str(serial_dir / f"drive{i + 1}-{port}")
        if drive.get("ci_terminal") is True:
            drive["ci_terminal"] = ANY_PORT
        drives.append(drive)
    return {"bus": [bus], "drive": drives}


def to_free_ports(doc: Dict[str, Any], serial_dir: Path,
                  base_dir: Optional[Path] = None) -> Dict[str, Any]:
    """A user's cell file with every address the cell listens on moved to a free loopback port
    (socketcand servers, Modbus servers, CI terminals) and every pty link into `serial_dir`, so
    that cells run side by side; what the cell joins or bridges (`join`, `socketcan`, EtherCAT
    interfaces) stays as it is. A relative `eds` is made absolute from `base_dir` (the cell
    file's folder: the binary reads it relative to the file, which moves)."""
    out = dict(doc)
    buses = out.get("bus")
    if isinstance(buses, Mapping):
        buses = [buses]
    if buses is None:
        buses = [{}]
    new_buses = []
    for b in buses:
        b = dict(b)
        if b.get("socketcand", None) != "":
            b["socketcand"] = ANY_PORT
        new_buses.append(b)
    out["bus"] = new_buses
    drives = []
    for i, d in enumerate(out.get("drive", [])):
        d = dict(d)
        if "modbus" in d or str(d.get("device", "")) in MODBUS_DEVICES:
            d["modbus"] = ANY_PORT
        eds = d.get("eds")
        if isinstance(eds, str) and base_dir is not None and not Path(eds).is_absolute():
            d["eds"] = str((base_dir / eds).resolve())
        if d.get("ci_terminal"):
            d["ci_terminal"] = ANY_PORT
        for port in ("rs232", "rs485"):
            if d.get(port):
                d[port] = str(serial_dir / f"drive{i + 1}-{port}-{Path(str(d[port])).name}")
        drives.append(d)
    out["drive"] = drives
    return out


def read_config(config: Union[str, Path]) -> Tuple[Dict[str, Any], Optional[Path]]:
    """A cell file's content and its folder: `config` is a path, or the TOML text itself (a
    string with a newline or a `=` that names no file; its folder is none)."""
    if isinstance(config, Path):
        return loads(config.read_text()), config.resolve().parent
    text = str(config)
    if "\n" not in text:
        path = Path(text)
        if "=" not in text or path.is_file():
            return loads(path.read_text()), path.resolve().parent
    return loads(text), None


__all__ = ["ANY_PORT", "DeviceSpec", "dumps", "from_devices", "loads", "read_config",
           "to_free_ports"]
