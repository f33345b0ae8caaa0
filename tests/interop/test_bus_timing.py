"""A CAN bus with a bit rate, in real time over socketcand: a python-canopen master sends SYNC
every 10 ms to 20 CMMP-AS whose TPDO1 is synchronous, on a 500 kbit/s bus. The bus load the
twin reports (web console /api/buses, from the control handle) and the load `drivetwin monitor
--bitrate` prints are within 5 % of the load the CAN bit formula gives for the frames a
python-can client saw on the bus.

The default cell's bus runs at its node's rate (a CMMP-AS with DIP6/DIP7 OFF: 125 kbit/s): an
SDO round trip in its trace takes at least the bit time of its two frames; a cell whose nodes
are set to different rates and that names no `bitrate` is refused.
"""

from __future__ import annotations

import json
import subprocess
import threading
import time
import urllib.error
import urllib.request

from conftest import CHANNEL, DRIVETWIN_BIN, add_node, frame_bits, read_pcap, run_cli, wait_until

BITRATE = 500_000
NODES = 20
SYNC_PERIOD = 0.010


def test_bus_load_at_500_kbit_matches_the_bit_formula(launch, connect, raw_bus, tmp_path):
    lines = ["[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"',
             f"bitrate = {BITRATE}", "late_after_us = 10000", ""]
    # Each drive's DIP7 and DIP8 ON: 500 kbit/s, CANopen on (CMMP-AS Tab. 2.4 / 2.5), the
    # node number its FCT base address; at another rate it would stay silent.
    for n in range(1, NODES + 1):
        lines += ["[[drive]]", 'device = "cmmp-as"', f"node = {n}", "[drive.objects]",
                  f'"1800:01" = {0x40000180 + n}', '"1800:02" = 1', "[drive.switches]",
                  'variant = "m3"', f"base_address = {n}", "on = [7, 8]", ""]
    cell = tmp_path / "bus.toml"
    cell.write_text("\n".join(lines))
    twin = launch(config=cell, extra=("--http", "127.0.0.1:0"))
    line = wait_until(lambda: next((l for l in twin.stdout_lines if l.startswith("web console on ")), None),
                      5.0, what="the web console")
    url = line.removeprefix("web console on ")

    seen: list[tuple[float, int, bytes]] = []
    stop = threading.Event()
    bus = raw_bus(twin)

    def listen():
        while not stop.is_set():
            m = bus.recv(0.1)
            if m is not None:
                seen.append((time.monotonic(), m.arbitration_id, bytes(m.data)))

    listener = threading.Thread(target=listen, daemon=True)
    listener.start()
    net = connect(twin)
    net.nmt.state = "OPERATIONAL"  # broadcast: every node
    net.sync.start(SYNC_PERIOD)
    monitor = None
    try:
        time.sleep(1.0)  # steady state
        start = time.monotonic()
        # Its output to a file: a pipe read only at the end would stall it.
        monitor_out = (tmp_path / "monitor.jsonl").open("w")
        monitor = subprocess.Popen(
            [str(DRIVETWIN_BIN), "monitor", "--bitrate", str(BITRATE), "--seconds", "2.2",
             "--json", "--socketcand", twin.addr],
            stdout=monitor_out, stderr=subprocess.PIPE, text=True)
        time.sleep(2.0)
        end = time.monotonic()
        buses = json.load(urllib.request.urlopen(url + "api/buses", timeout=5))
        _, err = monitor.communicate(timeout=10)
        monitor_out.close()
        out = (tmp_path / "monitor.jsonl").read_text()
    finally:
        if monitor is not None and monitor.poll() is None:
            monitor.kill()
        net.sync.stop()
        stop.set()
        listener.join(2)
    assert len(buses) == 1 and buses[0]["bitrate"] == BITRATE, buses
    b = buses[0]
    window = [(t, i, d) for t, i, d in seen if start <= t <= end]
    tpdos = sum(1 for _, i, _ in window if 0x181 <= i <= 0x180 + NODES)
    syncs = sum(1 for _, i, _ in window if i == 0x080)
    assert syncs > 100 and tpdos >= syncs * NODES * 0.9, (syncs, tpdos)
    computed = sum(frame_bits(i, d) for _, i, d in window) / BITRATE / (end - start) * 100
    # 21 frames of 47…80 bits every 10 ms at 500 kbit/s: about a third of the bus.
    assert 20 < computed < 50, computed
    assert abs(b["load_percent"] - computed) <= 0.05 * computed, (b, computed)
    # The monitor's windows: every frame it saw for its bit time, over 500 ms.
    assert monitor.returncode == 0, err
    loads = [json.loads(l)["bus_load_percent"] for l in out.splitlines() if "bus_load_percent" in l]
    assert len(loads) >= 3, out[-2000:]
    # The first window starts with the monitor's connection, part-way into a SYNC cycle.
    seen_by_monitor = sum(loads[1:]) / len(loads[1:])
    assert abs(seen_by_monitor - computed) <= 0.05 * computed, (loads, computed)
    # A late frame is real here: a master held off the CPU sends its missed SYNCs in a burst,
    # and 20 TPDOs behind each of them wait for the bus. Rare, never lost.
    assert b["dropped"] == 0 and b["late"] <= 0.02 * b["frames"], json.dumps(b)


def test_bus_faults_from_the_cell_file_and_the_web_console(launch, connect, eds_files, tmp_path):
    """A CMMP-AS disturbed by the cell file's plan goes bus off and to FAULT, its 12-1 EMCY
    (8120h) arriving once it is back; a Nanotec disturbed through the web console goes bus off
    and sends 8140h on recovery (CiA 301), both seen by python-canopen's EMCY consumer."""
    cell = tmp_path / "faults.toml"
    cell.write_text("\n".join([
        "[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', f"bitrate = {BITRATE}",
        "[[bus.disturb]]", "at_ms = 1500", "node = 1", "frames = 32", "",
        # Both set to the bus's 500 kbit/s: the CMMP-AS by DIP7 (DIP8: CANopen on), the Nanotec
        # by rotary switches 83h (node 3, bit rate from 2005h = 134, Nanotec §1.1.1).
        "[[drive]]", 'device = "cmmp-as"', "node = 1", "[drive.objects]", '"1017:00" = 20',
        "[drive.switches]", 'variant = "m3"', "on = [7, 8]", "",
        "[[drive]]", 'device = "nanotec-smci47s"', "node = 3", "[drive.objects]", '"1017:00" = 20',
        '"2005:00" = 134', "[drive.rotary_switches]", "left = 3", "right = 8", "",
    ]))
    twin = launch(config=cell, extra=("--http", "127.0.0.1:0"))
    line = wait_until(lambda: next((l for l in twin.stdout_lines if l.startswith("web console on ")), None),
                      5.0, what="the web console")
    url = line.removeprefix("web console on ")
    net = connect(twin)
    cmmp = net.add_node(1, str(eds_files["cmmp-as"]))
    nanotec = net.add_node(3, str(eds_files["nanotec-smci47s"]))
    wait_until(lambda: any(e.code == 0x8120 for e in cmmp.emcy.log), 5.0,
               what="the CMMP-AS's 12-1 EMCY after its planned bus off")
    assert cmmp.sdo[0x6041].raw & 0x0008, "FAULT"

    req = urllib.request.Request(url + "api/buses/0/disturb", method="POST",
                                 data=json.dumps({"node": 3, "frames": 32}).encode(),
                                 headers={"Content-Type": "application/json"})
    buses = json.load(urllib.request.urlopen(req, timeout=5))
    assert buses[0]["bitrate"] == BITRATE
    wait_until(lambda: [e.code for e in nanotec.emcy.log][-2:] == [0x8140, 0x0000], 5.0,
               what=f"8140h then 0000h from the Nanotec: {[hex(e.code) for e in nanotec.emcy.log]}")
    # Back on the bus, counters at zero: no node listed with errors.
    buses = json.load(urllib.request.urlopen(url + "api/buses", timeout=5))
    assert all(e["node"] != 3 for e in buses[0]["node_errors"]), buses
    bad = urllib.request.Request(url + "api/buses/0/disturb", method="POST",
                                 data=json.dumps({"node": 99, "frames": 32}).encode(),
                                 headers={"Content-Type": "application/json"})
    try:
        urllib.request.urlopen(bad, timeout=5)
        raise AssertionError("a node not on the bus is refused")
    except urllib.error.HTTPError as e:
        assert e.code == 404, e.code


DEFAULT_CELL_BITRATE = 125_000  # CMMP-AS DIP6/DIP7 OFF (Tab. 2.4)


def test_default_cell_sdo_round_trip_takes_the_frames_bit_time(launch, connect, eds_files, tmp_path):
    """`drivetwin run` with no bit rate: the bus takes the CMMP-AS's 125 kbit/s, and in the
    bus's trace each expedited SDO answer (581h) follows its request (601h, stamped as it
    reached the bus) by at least the bit time of both frames; python-canopen's round trip too."""
    trace = tmp_path / "bus.pcap"
    twin = launch("cmmp-as", 1, trace=trace)
    assert "bus vcan0: 125 kbit/s, its nodes' bit rate" in twin.stdout_lines, twin.stdout_lines
    net = connect(twin)
    node = add_node(net, 1, eds_files["cmmp-as"])
    took = []
    for _ in range(20):
        start = time.monotonic()
        assert node.sdo[0x1018][1].raw == 0x1D
        took.append(time.monotonic() - start)
    twin.stop()
    frames = read_pcap(trace)
    rounds = []
    for i, (t, can_id, _, data) in enumerate(frames):
        if can_id != 0x601:
            continue
        answer = next((f for f in frames[i + 1:] if f[1] == 0x581), None)
        assert answer is not None, f"no answer to the request at {t}"
        bit_time = (frame_bits(0x601, data) + frame_bits(0x581, answer[3])) / DEFAULT_CELL_BITRATE
        rounds.append((answer[0] - t, bit_time))
    assert len(rounds) >= 20, rounds
    # Two frames of about 120 bits at 125 kbit/s: about 2 ms (on the instant bus some 50 µs).
    # The request is stamped as the loop writes it to the trace, a few µs after it entered
    # the bus: 5 % of slack in the trace, none for the client, which sent before it entered.
    assert all(gap >= 0.95 * bits for gap, bits in rounds), rounds
    assert min(took) >= max(bits for _, bits in rounds), (took, rounds)


def test_instant_bus_on_the_command_line(launch, connect, eds_files):
    """`--bitrate instant` keeps the instant bus (frames cross at once) for fast tests."""
    twin = launch("cmmp-as", 1, extra=("--bitrate", "instant"))
    assert "bus vcan0: instant (frames cross at once)" in twin.stdout_lines, twin.stdout_lines
    node = add_node(connect(twin), 1, eds_files["cmmp-as"])
    assert node.sdo[0x1018][1].raw == 0x1D


def test_nodes_at_different_rates_are_refused_without_a_bitrate(tmp_path):
    """A CMMP-AS (125 kbit/s, its DIP6/DIP7 OFF) and a Kinco FD3 (2F81h = 50: 500 kbit/s) on one
    bus with no `bitrate`: the cell file is refused, exit code 2, naming each node's rate and
    the key that sets it. Set to one rate (2F81h = 12) they run."""
    cell = tmp_path / "cell.toml"

    def write(kinco_objects: list[str]):
        cell.write_text("\n".join([
            "[bus]", 'socketcand = "127.0.0.1:0"', f'channel = "{CHANNEL}"', "",
            "[[drive]]", 'device = "cmmp-as"', "node = 1", "",
            "[[drive]]", 'device = "kinco-fd3"', "node = 2", "[drive.objects]", *kinco_objects, "",
        ]))

    write([])
    r = run_cli("run", "--config", str(cell), "--http", "off")
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    assert "its nodes are set to different bit rates" in r.stderr, r.stderr
    assert "cmmp-as node 1: 125 kbit/s, set by [drive.switches]" in r.stderr, r.stderr
    assert 'kinco-fd3 node 2: 500 kbit/s, set by [drive.objects] "2F81:00"' in r.stderr, r.stderr
    assert "`bitrate`" in r.stderr, r.stderr
    write(['"2F81:00" = 12'])
    r = run_cli("run", "--config", str(cell), "--virtual-seconds", "0.1")
    assert r.returncode == 0, r.stderr
    assert "bus vcan0: 125 kbit/s, its nodes' bit rate" in r.stdout, r.stdout


def test_a_saved_kinco_can_baudrate_sets_the_bus_after_a_restart(launch, connect, eds_files, tmp_path):
    """A Kinco FD3 written CAN_Baudrate 2F81h := 25 (250 kbit/s, KINCO-CAN-06) and saved with
    Store_Data 2FF0h:01 := 1 over python-canopen comes back at 250 kbit/s after a restart with
    the same state directory, and so does the bus, whose cell names no `bitrate`: the stored
    value wins over the default, as the real drive powers on at its saved rate."""
    state = tmp_path / "kinco-state"
    twin = launch("kinco-fd3", 1, state_dir=state)
    assert "bus vcan0: 500 kbit/s, its nodes' bit rate" in twin.stdout_lines, twin.stdout_lines
    node = add_node(connect(twin), 1, eds_files["kinco-fd3"])
    node.sdo[0x2F81].raw = 25
    node.sdo[0x2FF0][1].raw = 1
    twin.stop()
    twin.start()
    assert "bus vcan0: 250 kbit/s, its nodes' bit rate" in twin.stdout_lines, twin.stdout_lines
    assert any(line.startswith('drive kinco-fd3 node 1: 250 kbit/s, set by "2F81:00" = 25')
               and "stored in" in line for line in twin.stdout_lines), twin.stdout_lines
    node = add_node(connect(twin), 1, eds_files["kinco-fd3"])
    assert node.sdo[0x2F81].raw == 25
