"""8. The drivetwin master commands (sdo, nmt, monitor) against the running twin."""

import json
import time

from conftest import HeartbeatLog, free_port, run_cli


def _json(r):
    assert r.stdout.strip(), f"no JSON on stdout; exit {r.returncode}, stderr {r.stderr!r}"
    return json.loads(r.stdout)


def _value(j):
    """The decoded value; the JSON carries it as a number or as its decimal text."""
    v = j["value"]
    return int(v) if isinstance(v, str) else v


def test_cli_sdo_read_identity_json(cmmp):
    r = run_cli("sdo", "read", "1", "1018", "1", "--socketcand", cmmp.addr, "--json")
    assert r.returncode == 0, r.stderr
    j = _json(r)
    assert _value(j) == 29
    assert j["index"] == "0x1018" and j["sub"] == 1 and j["node"] == 1
    assert j["data"].upper() == "1D000000"
    # plain text output
    r = run_cli("sdo", "read", "1", "0x1018", "1", "--socketcand", cmmp.addr)
    assert r.returncode == 0 and r.stdout.strip() == "29", (r.stdout, r.stderr)


def test_cli_sdo_read_string_with_device_type(cmmp):
    r = run_cli("sdo", "read", "1", "1008", "0", "--device", "cmmp-as", "--json",
                "--socketcand", cmmp.addr)
    assert r.returncode == 0, r.stderr
    assert _json(r)["value"] == "CMMP-AS-C2-3A-M3"


def test_cli_sdo_read_missing_object_exits_5_with_abort_code(cmmp):
    r = run_cli("sdo", "read", "1", "3000", "0", "--socketcand", cmmp.addr, "--json")
    assert r.returncode == 5, (r.returncode, r.stdout, r.stderr)
    assert _json(r)["abort_code"] == "0x06020000"


def test_cli_sdo_write_then_read(cmmp, node_of):
    r = run_cli("sdo", "write", "1", "1017", "0", "500", "--type", "u16", "--socketcand", cmmp.addr)
    assert r.returncode == 0, r.stderr
    r = run_cli("sdo", "read", "1", "1017", "0", "--type", "u16", "--json", "--socketcand", cmmp.addr)
    assert r.returncode == 0, r.stderr
    assert _value(_json(r)) == 500
    # python-canopen sees the same value
    assert node_of(cmmp).sdo[0x1017].raw == 500
    # a write to a read-only object: exit 5, abort code in the JSON
    r = run_cli("sdo", "write", "1", "6041", "0", "5", "--type", "u16", "--json",
                "--socketcand", cmmp.addr)
    assert r.returncode == 5, (r.returncode, r.stdout, r.stderr)
    assert _json(r)["abort_code"] == "0x06010002"


def test_cli_sdo_write_without_type_is_usage_error(cmmp):
    r = run_cli("sdo", "write", "1", "1017", "0", "500", "--socketcand", cmmp.addr)
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)


def test_cli_nmt_stop_then_sdo_times_out(cmmp, node_of):
    node = node_of(cmmp)
    hb = HeartbeatLog(node)
    node.sdo[0x1017].raw = 100
    r = run_cli("nmt", "stop", "1", "--socketcand", cmmp.addr)
    assert r.returncode == 0, r.stderr
    hb.wait_for(0x04, 0, timeout=1.5)
    t0 = time.monotonic()
    r = run_cli("sdo", "read", "1", "1018", "1", "--socketcand", cmmp.addr, "--json",
                "--timeout-ms", "300")
    assert r.returncode == 4, (r.returncode, r.stdout, r.stderr)
    assert time.monotonic() - t0 < 3
    r = run_cli("nmt", "start", "1", "--socketcand", cmmp.addr, "--json")
    assert r.returncode == 0, r.stderr
    assert _json(r) == {"nmt": "start", "node": 1}
    hb.wait_for(0x05, hb.mark(), timeout=1.5)
    r = run_cli("sdo", "read", "1", "1018", "1", "--socketcand", cmmp.addr)
    assert r.returncode == 0 and r.stdout.strip() == "29"


def test_cli_connection_refused_exits_3():
    port = free_port()  # nothing listens there
    for args in (("sdo", "read", "1", "1018", "1"), ("nmt", "start", "1"),
                 ("monitor", "--count", "1", "--seconds", "1")):
        r = run_cli(*args, "--socketcand", f"127.0.0.1:{port}", "--json")
        assert r.returncode == 3, (args, r.returncode, r.stdout, r.stderr)


def test_cli_monitor_sees_heartbeats(cmmp, node_of):
    node_of(cmmp).sdo[0x1017].raw = 100
    t0 = time.monotonic()
    r = run_cli("monitor", "--count", "3", "--seconds", "10", "--json", "--socketcand", cmmp.addr)
    assert r.returncode == 0, r.stderr
    assert time.monotonic() - t0 < 5
    frames = [json.loads(line) for line in r.stdout.splitlines() if line.strip()]
    assert len(frames) == 3, r.stdout
    for f in frames:
        assert f["id"] == 0x701 and f["data"] == "7F" and f["node"] == 1, f
        assert "heartbeat" in f["text"].lower()


def test_cli_monitor_stops_after_seconds(cmmp):
    t0 = time.monotonic()
    r = run_cli("monitor", "--seconds", "0.5", "--json", "--socketcand", cmmp.addr)
    elapsed = time.monotonic() - t0
    assert r.returncode == 0, (r.returncode, r.stderr)
    assert elapsed < 3, elapsed


def test_devices_lists_the_nanotec_personalities():
    r = run_cli("devices")
    assert r.returncode == 0, r.stderr
    names = [line.split()[0] for line in r.stdout.splitlines() if line.strip()]
    assert {"nanotec-smci47s", "nanotec-pd4n", "cmmp-as"} <= set(names), r.stdout
    assert any(line.startswith("nanotec-smci47s SMCI47-S (Nanotec") for line in r.stdout.splitlines())


def test_version_names_the_device_files_the_binary_carries():
    """`drivetwin --version`: the version, then every personality `drivetwin devices` lists
    with its product; `-V` the version alone."""
    r = run_cli("--version", check=True)
    lines = r.stdout.splitlines()
    assert lines[0].startswith("drivetwin 0.") and lines[1].startswith("device files"), lines
    devices = run_cli("devices", check=True).stdout.split("\n")
    names = [line.split()[0] for line in devices if line.strip()]
    assert len(names) >= 7
    listed = [line.split()[0] for line in lines[2:]]
    assert listed == names, (listed, names)
    assert run_cli("-V", check=True).stdout.strip() == lines[0]
