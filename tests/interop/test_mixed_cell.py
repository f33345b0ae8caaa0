"""One cell, many front ends, one clock: a cell file with a CMMP-AS on socketcand, a CMMP-AS on
EtherCAT and a CMMO-ST on Modbus TCP, served by one `drivetwin run` (one cell loop).

python-canopen moves the first (profile position), pysoem runs the second in cyclic synchronous
position and pymodbus homes the third, all at the same time. With the testing key
`allow_unreal_interfaces`, one CMMP-AS is a CANopen node and an EtherCAT slave at once: a value
written over CoE is read back over SDO and the other way round, and a controlword written over
CoE shows in the next CANopen TPDO (the statusword, TPDO1 on change).

The EtherCAT segment is a veth pair in this namespace: the twin answers on one end, SOEM sends
on the other. Needs root (raw sockets) and `ip` (iproute2); skips with a message otherwise.
"""

from __future__ import annotations

import json
import os
import shutil
import urllib.request
import struct
import threading
import time

import pytest
from canopen.profiles.p402 import BaseNode402
from pymodbus.client import ModbusTcpClient

from conftest import CHANNEL, HOST, free_port, ip, ip_steps, wait_until
from test_ethercat import _assign_csp_pdos, _csp_cycle, _csp_to_op, _state_ok, _wait_cycle
from test_fhpp_homing import REV, home_to_the_negative_stop

pysoem = pytest.importorskip("pysoem", reason="pysoem is not installed (pip install pysoem)")

FESTO = 0x1D


@pytest.fixture
def veth_pair():
    """A veth pair in this namespace: (twin-side, master-side) interface names."""
    if os.geteuid() != 0:
        pytest.skip("EtherCAT over veth needs root (raw sockets)")
    if shutil.which("ip") is None:
        pytest.skip("`ip` (iproute2) is not installed")
    tag = f"{os.getpid() % 100000}"
    twin_if, master_if = f"dtwMa{tag}", f"dtwMb{tag}"
    steps = [
        ("link", "add", master_if, "type", "veth", "peer", "name", twin_if),
        ("link", "set", twin_if, "up"),
        ("link", "set", master_if, "up"),
    ]
    try:
        ip_steps(steps)
        yield twin_if, master_if
    finally:
        ip("link", "del", master_if)


def console_url(twin) -> str:
    line = wait_until(lambda: next((l for l in twin.stdout_lines if l.startswith("web console on ")), None),
                      5.0, what="the 'web console on' line")
    return line.removeprefix("web console on ")


def _cmmp_lines(node: int) -> list[str]:
    # Heartbeat for python-canopen, and CiA 402's FAULT statusword (as the default cell has it).
    return ["[[drive]]", 'device = "cmmp-as"', f"node = {node}",
            "[drive.objects]", '"1017:00" = 1000', '"6510:F0" = 0x80']


def _run_threads(work: dict) -> dict:
    """Runs each callable on a thread of its own, all at once; returns the errors by name."""
    errors: dict = {}
    start = threading.Barrier(len(work))

    def run(name, fn):
        try:
            start.wait(10)
            fn()
        except BaseException as e:  # noqa: BLE001 - reported below with its name
            errors[name] = e

    threads = [threading.Thread(target=run, args=(n, f), daemon=True) for n, f in work.items()]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not any(t.is_alive() for t in threads), "a client hung"
    return errors


def test_canopen_ethercat_and_modbus_drives_move_at_once(launch, connect, eds_files, tmp_path,
                                                          veth_pair):
    twin_if, master_if = veth_pair
    modbus_port = free_port()
    cell = tmp_path / "mixed.toml"
    cell.write_text("\n".join([
        "[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', "",
        *_cmmp_lines(1), "",
        "[[drive]]", 'device = "cmmp-as"', "node = 2", 'interfaces = ["ethercat"]',
        f'ethercat = "{twin_if}"', "",
        "[[drive]]", 'device = "cmmo-st"', f'modbus = "{HOST}:{modbus_port}"',
        "[drive.stepper]", 'mode = "closed-loop"', "load_torque = 0.005",
        "[drive.axis]", "end_stops = [-1.5, 10.0]", 'index_pulse = "none"', "",
    ]))
    twin = launch(config=cell, extra=("--http", "127.0.0.1:0"))
    lines = twin.stdout_lines
    assert any(f"EtherCAT on {twin_if}: 1 slave" in l for l in lines), lines
    assert f"modbus server on {HOST}:{modbus_port}" in lines, lines
    # The control handle (here through the web console) has the three drives of the cell.
    url = console_url(twin)
    drives = json.load(urllib.request.urlopen(url + "api/drives", timeout=5))
    assert [(d["device"], d["interface"]) for d in drives] == [
        ("cmmp-as", "canopen"), ("cmmo-st", "modbus-tcp"), ("cmmp-as", "ethercat")], drives

    net = connect(twin)
    node = BaseNode402(1, str(eds_files["cmmp-as"]))
    net.add_node(node)
    node.nmt.wait_for_heartbeat(3)
    node.setup_402_state_machine()

    master = pysoem.Master()
    master.open(master_if)
    modbus = ModbusTcpClient(HOST, port=modbus_port, timeout=2, retries=0)
    assert modbus.connect()
    figures: dict = {}
    try:
        assert master.config_init() == 1, "one slave on the wire"
        slave = master.slaves[0]
        assert (slave.man, "CMMP" in slave.name) == (FESTO, True), slave.name
        _assign_csp_pdos(slave)
        assert master.config_map() == 12
        assert _state_ok(master, pysoem.SAFEOP_STATE), f"Safe-Op: {slave.al_status:#x}"

        def canopen_move():
            node.op_mode = "PROFILED POSITION"
            node.state = "OPERATION ENABLED"
            node.sdo[0x607A].raw = 4 * 65536
            node.sdo[0x6081].raw = 1200
            node.sdo[0x6083].raw = 12000
            node.sdo[0x6084].raw = 12000
            node.controlword = 0x1F
            wait_until(lambda: node.statusword & 0x1000, 1.0, what="set-point acknowledge")
            node.controlword = 0x0F
            wait_until(lambda: node.statusword & 0x0400, 5.0, interval=0.005, what="target reached")
            figures["canopen"] = node.sdo[0x6064].raw

        def ethercat_csp():
            cycle = _csp_cycle(master, slave)
            pos = _csp_to_op(master, slave, cycle, 0.002)
            target, bad = pos, 0
            for cw, want in ((0x06, 0x21), (0x07, 0x23), (0x0F, 0x27)):
                for _ in range(400):
                    wkc, sw, pos = cycle(cw, target)
                    bad += wkc != master.expected_wkc
                    if sw & 0x6F == want:
                        break
                    time.sleep(0.002)
                assert sw & 0x6F == want, f"statusword {sw:#06x} waiting for {want:#x}"
            start, step, nxt = target, 327, time.monotonic()
            for n in range(1000):  # 300 rpm for 1000 cycles, then hold
                if n < 900:
                    target += step
                wkc, sw, pos = cycle(0x0F, target)
                bad += wkc != master.expected_wkc
                nxt = _wait_cycle(nxt + 0.001)
            assert bad == 0, f"{bad} cycles with a wrong working counter"
            assert sw & 0x6F == 0x27, f"statusword {sw:#06x}"
            figures["ethercat"] = (start, pos, target)

        def modbus_home():
            home_to_the_negative_stop(modbus, -1.5 * REV)
            figures["modbus"] = True

        errors = _run_threads({"canopen": canopen_move, "ethercat": ethercat_csp,
                               "modbus": modbus_home})
        assert not errors, errors
    finally:
        modbus.close()
        master.close()
    assert abs(figures["canopen"] - 4 * 65536) <= 1800, figures
    start, pos, target = figures["ethercat"]
    assert abs(pos - target) < 200 and pos - start > 900 * 327 - 200, figures
    # The CAN drive and the EtherCAT drive are two drives: the CAN one never saw CSP.
    assert node.sdo[0x6061].raw == 1
    plant = json.load(urllib.request.urlopen(url + "api/drives/2/plant", timeout=5))
    assert plant["kind"] == "servo" and abs(plant["position"] - pos) < 2000, plant


def test_one_drive_on_canopen_and_ethercat_at_once(launch, connect, eds_files, tmp_path,
                                                    veth_pair):
    twin_if, master_if = veth_pair
    cell = tmp_path / "both.toml"
    cell.write_text("\n".join([
        "[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', "",
        *_cmmp_lines(1)[:3], 'interfaces = ["canopen", "ethercat"]',
        "allow_unreal_interfaces = true", f'ethercat = "{twin_if}"',
        *_cmmp_lines(1)[3:], "",
    ]))
    twin = launch(config=cell)
    assert any(f"EtherCAT on {twin_if}: 1 slave" in l for l in twin.stdout_lines), twin.stdout_lines
    net = connect(twin)
    node = BaseNode402(1, str(eds_files["cmmp-as"]))
    net.add_node(node)
    node.nmt.wait_for_heartbeat(3)

    master = pysoem.Master()
    master.open(master_if)
    try:
        assert master.config_init() == 1
        slave = master.slaves[0]
        # CoE → SDO.
        slave.sdo_write(0x6065, 0, struct.pack("<I", 12345))
        assert node.sdo[0x6065].raw == 12345
        # SDO → CoE.
        node.sdo[0x6067].raw = 777
        assert struct.unpack("<I", slave.sdo_read(0x6067, 0))[0] == 777

        # A controlword over CoE is in the next CANopen TPDO1 (the statusword, on change).
        node.tpdo.read()
        assert node.tpdo[1].map[0].index == 0x6041
        # TPDO1 is switched off at power-on (1800h:01 = C0000181h): on, on change.
        node.tpdo[1].enabled = True
        node.tpdo[1].trans_type = 255
        node.tpdo[1].save()
        seen = []
        node.tpdo[1].add_callback(lambda m: seen.append(m[0].raw))
        node.nmt.state = "OPERATIONAL"
        wait_until(lambda: node.nmt.state == "OPERATIONAL", 2.0, what="operational")
        slave.sdo_write(0x6040, 0, struct.pack("<H", 0x06))
        wait_until(lambda: any(sw & 0x6F == 0x21 for sw in seen), 2.0,
                   what=f"statusword 0x21 in a TPDO (seen {[hex(s) for s in seen]})")
        assert node.sdo[0x6040].raw == 0x06

        assert struct.unpack("<H", slave.sdo_read(0x6041, 0))[0] & 0x6F == 0x21
    finally:
        master.close()
