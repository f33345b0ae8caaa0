"""CiA 301 services beyond SDO against the real binary: PDO mapping with python-canopen's own
PdoMap.read()/save(), SYNC-driven and event-driven TPDOs, RPDOs on SYNC, EMCY received by
python-canopen's EMCY consumer, node guarding, LSS fastscan with python-canopen's LssMaster,
and SDO service under a SYNC/RPDO flood."""

from __future__ import annotations

import threading
import time

import can
import canopen
import pytest

from conftest import map_pdo, recv_id, wait_until


def _pre_op(node):
    node.nmt.wait_for_heartbeat(3)
    assert node.nmt.state == "PRE-OPERATIONAL"


def test_pdo_remap_with_python_canopen_save_and_read(cmmp, node_of):
    node = node_of(cmmp)
    _pre_op(node)
    node.tpdo.read()
    node.rpdo.read()
    # Defaults of the manual (CMMP-PDO-10 and CMMP-PDO-15): TPDO1 statusword, disabled.
    assert [v.index for v in node.tpdo[1].map] == [0x6041]
    assert not node.tpdo[1].enabled
    map_pdo(node.tpdo[3], [0x6041, 0x6064], trans_type=2)
    map_pdo(node.rpdo[3], [0x6040, 0x607A], trans_type=1)
    # A fresh read sees exactly what was saved.
    node.tpdo.read()
    node.rpdo.read()
    assert node.tpdo[3].cob_id == 0x381 and node.tpdo[3].trans_type == 2 and node.tpdo[3].enabled
    assert [(v.index, v.length) for v in node.tpdo[3].map] == [(0x6041, 16), (0x6064, 32)]
    assert node.rpdo[3].cob_id == 0x401 and node.rpdo[3].trans_type == 1 and node.rpdo[3].enabled
    assert [(v.index, v.length) for v in node.rpdo[3].map] == [(0x6040, 16), (0x607A, 32)]


def test_sync_driven_tpdo_and_rpdo_taking_effect_on_sync(cmmp, node_of):
    node = node_of(cmmp)
    _pre_op(node)
    node.tpdo.read()
    node.rpdo.read()
    node.tpdo[3].trans_type = 2  # statusword + position, every 2nd SYNC
    node.tpdo[3].enabled = True
    node.tpdo[3].save()
    node.rpdo[3].trans_type = 1  # controlword + target position, applied at SYNC
    node.rpdo[3].enabled = True
    node.rpdo[3].save()
    node.nmt.state = "OPERATIONAL"
    wait_until(lambda: node.nmt.state == "OPERATIONAL", 2, what="OPERATIONAL heartbeat")
    got = []
    node.tpdo[3].add_callback(lambda m: got.append(m.data))
    for _ in range(6):
        node.network.sync.transmit()
        time.sleep(0.03)
    wait_until(lambda: len(got) >= 3, 1, what="3 TPDO3")
    time.sleep(0.1)
    assert len(got) == 3, "every 2nd of 6 SYNCs"
    node.rpdo[3]["controlword"].raw = 0x000F
    node.rpdo[3]["target_position"].raw = 123456
    node.rpdo[3].transmit()
    time.sleep(0.1)
    assert node.sdo[0x607A].raw == 0, "synchronous RPDO waits for the SYNC"
    node.network.sync.transmit()
    wait_until(lambda: node.sdo[0x607A].raw == 123456, 1, what="target position after SYNC")
    assert node.sdo[0x6040].raw == 0x000F


def test_event_driven_tpdo_respects_inhibit_time(cmmp, node_of, raw_bus):
    node = node_of(cmmp)
    _pre_op(node)
    node.tpdo.read()
    t = node.tpdo[2]
    # Without drive logic nothing moves by itself: map the mode command (6060h), which SDO
    # writes change, so each write is a change of the TPDO's data.
    t.clear()
    t.add_variable(0x6060)
    t.trans_type = 255
    t.inhibit_time = 500  # 100 µs units: 50 ms
    t.enabled = True
    t.save()
    bus = raw_bus(cmmp)
    node.nmt.state = "OPERATIONAL"
    assert recv_id(bus, 0x281, 1.0) is not None, "sent once on entering Operational"
    for mode in [1, 3, 4, 1, 3, 4, 1, 3, 4, 6]:
        node.sdo[0x6060].raw = mode
    stamps, last = [], None
    while True:
        m = recv_id(bus, 0x281, 0.3)
        if m is None:
            break
        stamps.append(m.timestamp)
        last = m.data
    assert 1 <= len(stamps) <= 6, stamps
    assert last == bytes([6]), "the last frame carries the final value"
    gaps = [b - a for a, b in zip(stamps, stamps[1:])]
    assert all(g >= 0.045 for g in gaps), gaps


def test_short_rpdo_raises_emcy_8210_seen_by_python_canopen(cmmp, node_of):
    node = node_of(cmmp)
    _pre_op(node)
    node.rpdo.read()
    node.rpdo[4].enabled = True  # controlword + target velocity: 6 bytes
    node.rpdo[4].save()
    node.nmt.state = "OPERATIONAL"
    wait_until(lambda: node.nmt.state == "OPERATIONAL", 2, what="OPERATIONAL")
    # The EMCY can come before emcy.wait() would start listening: look at the log instead.
    mark = len(node.emcy.log)
    node.network.send_message(0x501, b"\x0f\x00")
    wait_until(lambda: any(e.code == 0x8210 for e in node.emcy.log[mark:]), 2, what="EMCY 8210h")
    err = next(e for e in node.emcy.log[mark:] if e.code == 0x8210)
    assert err.code == 0x8210
    assert err.register == 0x11  # generic + communication
    assert node.sdo[0x1001].raw == 0x11
    assert node.sdo[0x6040].raw == 0, "a short RPDO is not processed"
    # The right length again: processed, and EMCY 0000h clears python-canopen's active list.
    mark = len(node.emcy.log)
    node.network.send_message(0x501, b"\x0f\x00\x10\x27\x00\x00")
    wait_until(lambda: any(e.code == 0x0000 for e in node.emcy.log[mark:]), 2, what="EMCY 0000h")
    wait_until(lambda: node.sdo[0x6040].raw == 0x0F, 1, what="controlword from RPDO4")
    assert node.sdo[0x60FF].raw == 10000
    assert node.emcy.active == []


def test_node_guarding_replies_with_toggle_bit(cmmp, node_of, raw_bus):
    node = node_of(cmmp)
    _pre_op(node)
    node.sdo[0x1017].raw = 0  # heartbeat would take priority (CMMP-AS §3.9)
    bus = raw_bus(cmmp)
    replies = []
    for _ in range(3):
        # python-can over socketcand carries no RTR: the request is a zero-length frame.
        bus.send(can.Message(arbitration_id=0x701, data=b"", is_extended_id=False, is_remote_frame=True))
        m = recv_id(bus, 0x701, 1.0)
        assert m is not None
        replies.append(m.data[0])
    assert replies == [0x7F, 0xFF, 0x7F]
    node.nmt.send_command(0x01)
    time.sleep(0.05)
    bus.send(can.Message(arbitration_id=0x701, data=b"", is_extended_id=False))
    m = recv_id(bus, 0x701, 1.0)
    assert m is not None and m.data[0] == 0x85


def test_lss_fastscan_finds_an_unconfigured_drive_and_gives_it_an_id(launch, connect, tmp_path, eds_files):
    state = tmp_path / "lss-state"
    twin = launch("cmmp-as", 255, state_dir=state)
    net = connect(twin)
    time.sleep(0.2)
    ok, lss_id = net.lss.fast_scan()
    assert ok, "python-canopen LssMaster.fast_scan found the node"
    assert lss_id[0] == 0x1D  # Festo
    net.lss.configure_node_id(5)
    net.lss.store_configuration()
    node = net.add_node(5, str(eds_files["cmmp-as"]))
    # The boot-up can come before nmt.wait_for_bootup() would start listening: record it.
    bootups = []
    net.subscribe(0x705, lambda cob_id, data, timestamp: bootups.append(bytes(data)))
    net.lss.send_switch_state_global(net.lss.WAITING_STATE)
    wait_until(lambda: b"\x00" in bootups, 2, what="boot-up of node 5")
    assert node.sdo[0x1018][1].raw == 0x1D
    assert node.sdo[0x1400][1].raw == 0xC0000205, "node-relative COB-IDs follow the new ID"
    # The stored node-ID comes back after a restart.
    twin.stop()
    twin.start()
    net2 = connect(twin)
    node2 = net2.add_node(5, str(eds_files["cmmp-as"]))
    assert node2.sdo[0x1018][1].raw == 0x1D


def test_sync_and_rpdo_flood_never_stalls_sdo(launch, node_of, raw_bus):
    # The instant bus: this is a test of the cell loop under a flood of client frames. On a
    # real bus SYNC (080h) and RPDO1 (201h) at its limit win every arbitration against the
    # SDO request (601h), which would then wait as long as the flood lasts.
    cmmp = launch("cmmp-as", 1, extra=("--bitrate", "instant"))
    node = node_of(cmmp)
    _pre_op(node)
    node.rpdo.read()
    node.rpdo[1].enabled = True
    node.rpdo[1].save()
    node.nmt.state = "OPERATIONAL"
    flood = raw_bus(cmmp)
    stop = threading.Event()
    sent = [0]

    def flooder():
        # At the bus limit: a 1 Mbit/s CAN bus carries about 8000 such short frames a second,
        # so 40 SYNC + 40 RPDO every 10 ms.
        sync = can.Message(arbitration_id=0x080, data=b"", is_extended_id=False)
        rpdo = can.Message(arbitration_id=0x201, data=b"\x06\x00", is_extended_id=False)
        next_burst = time.monotonic()
        while not stop.is_set():
            for _ in range(40):
                flood.send(sync)
                flood.send(rpdo)
                sent[0] += 2
            # Read what the bus sends back (the TPDOs the SYNCs ask for): a client that never
            # reads is a slow consumer, and the twin drops it once its socket buffer is full.
            for _ in range(400):
                if flood.recv(timeout=0) is None:
                    break
            next_burst += 0.01
            time.sleep(max(0.0, next_burst - time.monotonic()))

    t = threading.Thread(target=flooder, daemon=True)
    t.start()
    reads = 0
    try:
        end = time.monotonic() + 1.5
        while time.monotonic() < end:
            assert node.sdo[0x1018][1].raw == 0x1D
            reads += 1
    finally:
        stop.set()
        t.join(2)
    assert sent[0] > 5000, sent
    assert reads > 50, reads
    assert node.sdo[0x6040].raw == 6


def test_trace_of_a_pdo_session_decodes_in_tshark(launch, node_of, tmp_path):
    import shutil
    import subprocess

    tshark = shutil.which("tshark")
    if tshark is None:
        pytest.skip("tshark (Debian package tshark) is not installed")
    trace = tmp_path / "pdo.pcap"
    twin = launch("cmmp-as", 1, trace=trace)
    node = node_of(twin)
    _pre_op(node)
    node.tpdo.read()
    node.tpdo[3].trans_type = 1
    node.tpdo[3].enabled = True
    node.tpdo[3].save()
    node.nmt.state = "OPERATIONAL"
    time.sleep(0.05)
    for _ in range(3):
        node.network.sync.transmit()
        time.sleep(0.01)
    time.sleep(0.1)
    twin.stop()
    out = subprocess.run([tshark, "-r", str(trace), "-d", "can.subdissector,canopen"],
                         capture_output=True, text=True, timeout=60).stdout
    assert out.count("SYNC") >= 3, out
    assert out.count("PDO3 (tx)") >= 3, out
    assert "NMT: Start remote node" in out, out
    assert "Default-SDO" in out, out
