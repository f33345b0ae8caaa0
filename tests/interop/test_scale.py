"""A whole machine: a cell of 127 nodes of mixed personalities on one bus, scanned by
`drivetwin scan` and read node by node by python-canopen; and one bus made of two twin
processes (`--socketcand-join`), seen whole by a master on a third connection.
"""

from __future__ import annotations

import json

from conftest import CHANNEL, cmmp_switches, run_cli, wait_until

# CiA 402 personalities answer 1000h with their device type; the test bench is a CiA 301 device.
PERSONALITIES = ["cmmp-as", "nanotec-smci47s", "testbench", "nanotec-pd4n"]


def drive(device: str, node: int) -> list[str]:
    """A `[[drive]]` on a 1 Mbit/s bus: a Nanotec's switches at its node-ID fix 1 Mbit/s; a
    CMMP-AS needs DIP6 and DIP7 ON."""
    lines = ["[[drive]]", f'device = "{device}"', f"node = {node}"]
    if device == "cmmp-as":
        lines += cmmp_switches(node)
    return lines + [""]


def test_127_nodes_of_mixed_personalities_pass_scan_and_sdo(launch, connect, eds_files, tmp_path):
    lines = ["[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', ""]
    for n in range(1, 128):
        lines += drive(PERSONALITIES[n % len(PERSONALITIES)], n)
    cell = tmp_path / "machine.toml"
    cell.write_text("\n".join(lines))
    twin = launch(config=cell)
    r = run_cli("scan", "--socketcand", twin.addr, "--channel", CHANNEL, "--timeout-ms", "2000",
                "--json", timeout=60)
    assert r.returncode == 0, r.stderr
    found = {n["node"]: n["device_type"] for n in json.loads(r.stdout)}
    assert sorted(found) == list(range(1, 128)), sorted(set(range(1, 128)) - set(found))

    net = connect(twin)
    for n in range(1, 128):
        node = net.add_node(n, str(eds_files[PERSONALITIES[n % len(PERSONALITIES)]]))
        node.sdo.RESPONSE_TIMEOUT = 2.0
        assert node.sdo[0x1000].raw == found[n], n
        # The vendor-ID as the personality's EDS gives it: every node answers for itself.
        assert node.sdo[0x1018][1].raw == node.object_dictionary[0x1018][1].default, n


def test_two_twin_processes_make_one_bus(launch, connect, raw_bus, eds_files, tmp_path):
    first = tmp_path / "first.toml"
    first.write_text("\n".join(["[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', "",
                                *drive("cmmp-as", 1), *drive("cmmp-as", 2)]))
    a = launch(config=first)
    # A master on a third connection, there before the second twin boots: it sees its boot-up.
    bus = raw_bus(a)
    second = tmp_path / "second.toml"
    second.write_text("\n".join(["[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', "",
                                 *drive("nanotec-smci47s", 3), *drive("testbench", 4)]))
    b = launch(config=second, extra=("--socketcand-join", a.addr))
    joined = f"joined socketcand server {a.addr}, channel {CHANNEL}"
    wait_until(lambda: joined in b.stdout_lines, 5.0, what=joined)
    boot = set()

    def booted():
        m = bus.recv(0.1)
        if m is not None and m.arbitration_id in (0x703, 0x704) and bytes(m.data) == b"\x00":
            boot.add(m.arbitration_id)
        return boot == {0x703, 0x704}

    wait_until(booted, 5.0, interval=0, what="the second twin's boot-up messages on the first's bus")

    # One master on the first twin's server reaches all four nodes.
    net = connect(a)
    for n, dev in ((1, "cmmp-as"), (2, "cmmp-as"), (3, "nanotec-smci47s"), (4, "testbench")):
        node = net.add_node(n, str(eds_files[dev]))
        node.sdo.RESPONSE_TIMEOUT = 2.0
        assert node.sdo[0x1018][1].raw == node.object_dictionary[0x1018][1].default, n
    # And one on the second twin's own server sees the first's nodes through it.
    other = connect(b)
    node = other.add_node(1, str(eds_files["cmmp-as"]))
    node.sdo.RESPONSE_TIMEOUT = 2.0
    node.sdo[0x6065].raw = 4321
    assert net.nodes[1].sdo[0x6065].raw == 4321


def test_two_cells_in_one_process_run_on_threads_of_their_own(launch, connect, eds_files, tmp_path):
    from conftest import HOST, free_port
    port = free_port()
    first = tmp_path / "first.toml"
    first.write_text("\n".join(["[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', "",
                                "[[drive]]", 'device = "cmmp-as"', "node = 1", ""]))
    second = tmp_path / "second.toml"
    second.write_text("\n".join(["[bus]", f'socketcand = "{HOST}:{port}"', f'channel = "{CHANNEL}"', "",
                                 "[[drive]]", 'device = "nanotec-smci47s"', "node = 1", ""]))
    twin = launch(config=first, extra=("--config", str(second)))
    wait_until(lambda: f"socketcand server on {HOST}:{port}, channel {CHANNEL}" in twin.stdout_lines,
               5.0, what="the second cell's server")
    # Two buses, two loops: node 1 on each is another drive.
    a = connect(twin).add_node(1, str(eds_files["cmmp-as"]))
    a.sdo.RESPONSE_TIMEOUT = 2.0
    b_twin = type("Other", (), {"port": port})()
    b = connect(b_twin).add_node(1, str(eds_files["nanotec-smci47s"]))
    b.sdo.RESPONSE_TIMEOUT = 2.0
    assert a.sdo[0x1018][1].raw == a.object_dictionary[0x1018][1].default
    assert b.sdo[0x1018][1].raw == b.object_dictionary[0x1018][1].default
    assert a.sdo[0x1018][1].raw != b.sdo[0x1018][1].raw, "Festo and Nanotec"
    threads = {p.read_text().strip() for p in __import__("pathlib").Path(f"/proc/{twin.proc.pid}/task").glob("*/comm")}
    assert {"cell", "cell-1"} <= threads, threads
