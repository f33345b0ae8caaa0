"""CMMP-AS node number and CAN activation from its switches (`[drive.switches]` in a cell
file, manual §2.3): what python-canopen sees on the bus."""

import socket

import canopen
import pytest

from conftest import CHANNEL, HOST, add_node, free_port, read_to_cr, wait_until


def _cell(path, drives):
    lines = ["[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', ""]
    for node, switches, extra in drives:
        lines += ["[[drive]]", 'device = "cmmp-as"', f"node = {node}", *extra, "[drive.objects]",
                  '"1017:00" = 100', "[drive.switches]", *switches, ""]
    path.write_text("\n".join(lines))
    return path


def test_dip_offset_27_and_dip8_off(launch, tmp_path, connect, eds_files):
    """CMMP-NODE-01: DIP 1, 2, 4, 5 ON with base 0 → node 27 (SDO 61B/59B, heartbeat 71B).
    CMMP-NODE-08: a drive with DIP8 OFF stays off the bus."""
    port = free_port()
    cfg = _cell(tmp_path / "cell.toml", [
        (2, ['variant = "m3"', "base_address = 40", "on = [1]"], []),
        (1, ['variant = "m3"', "on = [1, 2, 4, 5, 8]"], [f'ci_terminal = "{HOST}:{port}"']),
    ])
    twin = launch(config=cfg)
    assert any("node 27" in l and "125 kbit/s" in l for l in twin.stdout_lines), twin.stdout_lines
    assert any("node 41" in l and "deactivated" in l for l in twin.stdout_lines), twin.stdout_lines
    net = connect(twin)
    node = add_node(net, 27, eds_files["cmmp-as"])
    assert node.nmt.wait_for_heartbeat(timeout=3) == "PRE-OPERATIONAL"
    assert node.sdo[0x1018][1].raw == 0x1D
    assert node.sdo[0x1800][1].raw == 0xC0000180 + 27, "node-relative COB-IDs follow"
    for silent in (1, 41):
        ghost = add_node(net, silent, eds_files["cmmp-as"])
        ghost.sdo.RESPONSE_TIMEOUT = 0.3
        with pytest.raises(canopen.SdoCommunicationError):
            ghost.sdo[0x1018][1].raw
    # The second drive of the file is the first of the bus: its console reaches node 27.
    wait_until(lambda: any(l.startswith("CI terminal of drive 2 on") for l in twin.stdout_lines),
               5.0, what="the CI terminal line")
    with socket.create_connection((HOST, port), timeout=3) as s:
        f = s.makefile("rwb", buffering=0)
        f.write(b"?180001\r\n")
        assert read_to_cr(f) == b"=180001:C000019B\r"
