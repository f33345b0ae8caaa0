"""One cell, one loop. A cell file with two CAN buses ([[bus]]), a CMMP-AS on each
(both node 1: node-IDs are per bus), the first with its CI terminal, and a CMMO-ST on Modbus
TCP, all served by the one cell loop of one process: python-canopen on both buses, the CI
terminal and pymodbus at once."""

import socket

import canopen
import pytest
from pymodbus.client import ModbusTcpClient

from conftest import CHANNEL, HOST, add_node, free_port, read_to_cr, run_cli, wait_until
from test_fhpp_modbus import (CCON_RECORD_ENABLED, CPOS_HALT, SCON_ENABLED, cycle_until, exchange,
                              telegram)


def _cell(path, bus_b: int, ci: int, modbus: int):
    path.write_text(f"""
[[bus]]
name = "line-a"
socketcand = "127.0.0.1:1"      # --socketcand sets the first bus
channel = "{CHANNEL}"

[[bus]]
name = "line-b"
socketcand = "{HOST}:{bus_b}"
channel = "{CHANNEL}"

[[drive]]
device = "cmmp-as"
node = 1
bus = "line-a"
interfaces = ["canopen", "ci-terminal"]
ci_terminal = "{HOST}:{ci}"

[[drive]]
device = "cmmp-as"
node = 1
bus = "line-b"

[[drive]]
device = "cmmo-st"
modbus = "{HOST}:{modbus}"
interfaces = ["modbus-tcp"]
""")
    return path


def _network(port: int):
    net = canopen.Network()
    net.NOTIFIER_CYCLE = 0.05
    net.connect(interface="socketcand", host=HOST, port=port, channel=CHANNEL)
    return net


def test_two_buses_a_ci_terminal_and_modbus_on_one_loop(launch, tmp_path, eds_files):
    bus_b, ci, modbus = free_port(), free_port(), free_port()
    twin = launch(config=_cell(tmp_path / "cell.toml", bus_b, ci, modbus))
    wait_until(lambda: any(l.startswith("CI terminal of drive 1") for l in twin.stdout_lines),
               5.0, what="the CI terminal line")
    nets = [_network(twin.port), _network(bus_b)]
    console = socket.create_connection((HOST, ci), timeout=3)
    f = console.makefile("rwb", buffering=0)
    mb = ModbusTcpClient(HOST, port=modbus, timeout=3)
    try:
        a = add_node(nets[0], 1, eds_files["cmmp-as"])
        b = add_node(nets[1], 1, eds_files["cmmp-as"])
        # Each bus's node 1 is its own drive.
        a.sdo[0x607A].raw = 1111
        b.sdo[0x607A].raw = 2222
        assert a.sdo[0x607A].raw == 1111 and b.sdo[0x607A].raw == 2222
        # The CI terminal of the first drive sees what CANopen wrote, and the other way round.
        f.write(b"?607A00\r\n")
        assert read_to_cr(f) == b"=607A00:00000457\r"
        f.write(b"=607A00:00000D05\r\n")
        assert read_to_cr(f) == b"=607A00:00000D05\r"
        assert a.sdo[0x607A].raw == 0xD05
        # The CMMO-ST answers on Modbus TCP meanwhile.
        assert mb.connect()
        rr = mb.read_holding_registers(0, count=4)
        assert not rr.isError(), rr
        assert len(rr.registers) == 4
        # And the buses still answer after Modbus traffic.
        assert b.sdo[0x1018][1].raw == a.sdo[0x1018][1].raw
    finally:
        mb.close()
        console.close()
        for net in nets:
            net.disconnect()


def test_an_interface_combination_the_device_lacks_is_refused(tmp_path):
    """CMMP-AS §2.3: one fieldbus at a time; the error names the rule and the testing key."""
    from conftest import run_cli
    cell = tmp_path / "cell.toml"
    cell.write_text('[[drive]]\ndevice = "cmmp-as"\ninterfaces = ["canopen", "ethercat"]\n')
    r = run_cli("run", "--config", str(cell), "--socketcand", f"{HOST}:{free_port()}")
    assert r.returncode != 0
    assert "§2.3" in r.stderr and "allow_unreal_interfaces" in r.stderr, r.stderr


def test_two_cmmo_sts_each_on_its_own_modbus_address(launch, tmp_path):
    """Two CMMO-STs in one cell, each on the address of its `modbus` key, are two drives: the
    one enabled shows SCON.ENABLED, the other stays at its power-on bytes. `--modbus` gives one
    address, so with two CMMO-STs it is refused as a usage error (exit 2)."""
    ports = [free_port(), free_port()]
    cell = tmp_path / "cell.toml"
    cell.write_text("\n".join([
        "[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', "",
        "[[drive]]", 'device = "cmmp-as"', "node = 1", "",
        *(line for port in ports
          for line in ("[[drive]]", 'device = "cmmo-st"', f'modbus = "{HOST}:{port}"', "")),
    ]))
    r = run_cli("run", "--config", str(cell), "--modbus", f"{HOST}:{free_port()}", timeout=20)
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    assert "several CMMO-STs" in r.stderr, r.stderr

    twin = launch(config=cell)
    for port in ports:
        assert f"modbus server on {HOST}:{port}" in twin.stdout_lines, twin.stdout_lines
    first, second = (ModbusTcpClient(HOST, port=p, timeout=3, retries=0) for p in ports)
    try:
        assert first.connect() and second.connect()
        cycle_until(first, telegram(CCON_RECORD_ENABLED, CPOS_HALT),
                    lambda s: s["scon"] & SCON_ENABLED, what="the first CMMO-ST enabled")
        s = exchange(second, telegram(0, 0))
        assert (s["scon"], s["spos"]) == (0x10, 0x04), s  # power-on (CMMO-ST Example 1)
        assert exchange(first, telegram(CCON_RECORD_ENABLED, CPOS_HALT))["scon"] & SCON_ENABLED
    finally:
        first.close()
        second.close()
