"""9-10. Bus traces (pcap, candump) read by tshark and python-can, and the virtual clock:
deterministic, faster than real time."""

import shutil
import struct
import subprocess
import time

import can
import pytest

from conftest import HeartbeatLog, frame_bits, read_pcap, run_cli


def _tshark():
    path = shutil.which("tshark")
    if path is None:
        pytest.skip("tshark is not on PATH (apt-get install tshark)")
    return path


def _traffic(node):
    """Some SDO traffic (expedited, segmented, an abort) and an NMT start."""
    hb = HeartbeatLog(node)
    node.sdo[0x1017].raw = 100
    assert node.sdo[0x1018][1].raw == 0x1D
    assert node.sdo[0x1008].raw == "CMMP-AS-C2-3A-M3"
    import canopen
    with pytest.raises(canopen.SdoAbortedError):
        node.sdo.upload(0x3000, 0)
    node.nmt.state = "OPERATIONAL"
    hb.wait_for(0x05, 0, timeout=1.5)


def test_pcap_trace_decoded_by_tshark(launch, node_of, tmp_path):
    trace = tmp_path / "out.pcap"
    twin = launch("cmmp-as", 1, trace=trace)
    _traffic(node_of(twin))
    twin.stop()

    frames = read_pcap(trace)
    ids = [f[1] for f in frames]
    assert ids[0] == 0x701 and frames[0][3] == b"\x00", "the trace starts with the boot-up"
    assert (0x000, b"\x01\x01") in [(f[1], bytes(f[3])) for f in frames]
    assert 0x601 in ids and 0x581 in ids
    stamps = [f[0] for f in frames]
    assert stamps == sorted(stamps)

    tshark = _tshark()
    r = subprocess.run([tshark, "-r", str(trace), "-d", "can.subdissector,canopen"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    text = r.stdout
    assert "NMT Error Control: Boot-up" in text
    assert "NMT: Start remote node" in text
    assert "Default-SDO (rx): Initiate upload request" in text
    assert "Default-SDO (tx): Initiate upload response" in text
    assert "Upload segment response" in text
    assert "Default-SDO (tx): Abort transfer" in text
    assert "NMT Error Control: Operational" in text
    assert "Malformed" not in text

    r = subprocess.run([tshark, "-r", str(trace), "-d", "can.subdissector,canopen", "-T", "fields",
                        "-E", "separator=,", "-e", "canopen.sdo.main_idx", "-e",
                        "canopen.sdo.sub_idx", "-e", "canopen.sdo.abort_code", "-e",
                        "canopen.nmt_guard.state", "-e", "canopen.nmt_ctrl.cd"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    rows = [line.split(",") for line in r.stdout.splitlines()]
    assert ["0x1018", "0x01", "", "", ""] in rows
    assert ["0x3000", "0x00", "0x06020000", "", ""] in rows
    assert ["", "", "", "", "0x01"] in rows  # NMT start
    assert ["", "", "", "0x05", ""] in rows  # heartbeat OPERATIONAL
    assert len(rows) == len(frames)


def test_candump_trace_read_by_python_can(launch, node_of, tmp_path):
    trace = tmp_path / "out.log"
    twin = launch("cmmp-as", 1, trace=trace)
    _traffic(node_of(twin))
    twin.stop()

    msgs = list(can.LogReader(str(trace)))
    assert msgs, trace.read_text()[:500]
    assert (msgs[0].arbitration_id, bytes(msgs[0].data)) == (0x701, b"\x00")
    pairs = [(m.arbitration_id, bytes(m.data)) for m in msgs]
    assert (0x601, bytes.fromhex("4018100100000000")) in pairs
    assert (0x581, bytes.fromhex("431810011D000000")) in pairs
    assert (0x581, bytes.fromhex("8000300000000206")) in pairs
    assert (0x000, b"\x01\x01") in pairs
    assert (0x701, b"\x05") in pairs
    assert all(m.channel == "vcan0" for m in msgs)
    stamps = [m.timestamp for m in msgs]
    assert stamps == sorted(stamps)


INJECT = """\
(0.500000) vcan0 601#2B17100064000000
(1.000000) vcan0 000#0100
(1.500000) vcan0 601#4018100100000000
(2.000000) vcan0 601#4017100000000000
(2.500000) vcan0 601#4000300000000000
(3.000000) vcan0 601#4008100000000000
(3.000100) vcan0 601#6000000000000000
(3.000200) vcan0 601#7000000000000000
(3.000300) vcan0 601#7000000000000000
"""


def test_virtual_clock_is_deterministic_and_fast(tmp_path):
    inject = tmp_path / "in.log"
    inject.write_text(INJECT)
    out1, out2 = tmp_path / "out1.pcap", tmp_path / "out2.pcap"
    # The instant bus: the heartbeat producer's period read from the trace to the microsecond,
    # with no bit time in the stamps (test_virtual_clock_without_inject runs the real bus).
    instant = ("--bitrate", "instant")
    t0 = time.monotonic()
    r1 = run_cli("run", "--virtual-seconds", "5", "--inject", str(inject), "--trace", str(out1),
                 *instant)
    wall = time.monotonic() - t0
    assert r1.returncode == 0, r1.stderr
    assert wall < 2.5, f"5 virtual seconds took {wall:.2f} s of wall time"
    r2 = run_cli("run", "--virtual-seconds", "5", "--inject", str(inject), "--trace", str(out2),
                 *instant)
    assert r2.returncode == 0, r2.stderr
    assert out1.read_bytes() == out2.read_bytes(), "two runs of the same input differ"

    frames = read_pcap(out1)
    # the injected frames are on the bus at their timestamps
    injected = [(t, i, bytes(d)) for t, i, _, d in frames if i in (0x000, 0x601)]
    assert injected[0] == (pytest.approx(0.5, abs=1e-6), 0x601, bytes.fromhex("2B17100064000000"))
    assert injected[1] == (pytest.approx(1.0, abs=1e-6), 0x000, b"\x01\x00")
    assert len(injected) == 9

    responses = [bytes(d) for _, i, _, d in frames if i == 0x581]
    assert responses[:4] == [bytes.fromhex("6017100000000000"),  # 1017h := 100 ms
                             bytes.fromhex("431810011D000000"),  # 1018h:01 = 1Dh
                             bytes.fromhex("4B17100064000000"),  # 1017h = 100
                             bytes.fromhex("8000300000000206")]  # 3000h does not exist
    # 1008h upload: initiate, two correct segments, then a repeated toggle bit
    assert responses[4] == bytes.fromhex("4108100010000000")
    assert responses[5] == b"\x00CMMP-AS"
    assert responses[6] == b"\x10-C2-3A-"
    assert responses[7] == bytes.fromhex("8008100000000305")
    assert len(responses) == 8

    hb = [(t, bytes(d)) for t, i, _, d in frames if i == 0x701]
    assert hb[0] == (0.0, b"\x00"), "boot-up at time 0"
    beats = hb[1:]
    # 1017h = 100 ms from 0.5 s on: a heartbeat every 100 ms from 0.6 s to the end of the run
    assert beats[0][0] == pytest.approx(0.6, abs=1e-6)
    gaps = [round(b[0] - a[0], 6) for a, b in zip(beats, beats[1:])]
    assert set(gaps) == {0.1}, gaps
    assert len(beats) in (44, 45), f"{len(beats)} heartbeats in 0.6 .. 5 s"
    assert beats[-1][0] <= 5.0 + 1e-6
    # pre-operational until the NMT start at 1.0 s, operational after it
    assert all(d == b"\x7f" for t, d in beats if t < 1.0 - 1e-6)
    assert all(d == b"\x05" for t, d in beats if t >= 1.0 - 1e-6)
    assert any(d == b"\x05" for t, d in beats)


def test_virtual_clock_without_inject(tmp_path):
    out = tmp_path / "idle.pcap"
    r = run_cli("run", "--virtual-seconds", "10", "--trace", str(out))
    assert r.returncode == 0, r.stderr
    frames = read_pcap(out)
    # The default cell's bus at the CMMP-AS's 125 kbit/s: a frame is stamped once it has
    # crossed, its bit time after it was sent.
    def crossed(at: float, data: bytes) -> float:
        return pytest.approx(at + frame_bits(0x701, data) / 125_000, abs=1e-6)

    # the commissioned 1017h = 1000 ms: boot-up, then one heartbeat a second
    assert [(t, i, bytes(d)) for t, i, _, d in frames][0] == (crossed(0.0, b"\x00"), 0x701, b"\x00")
    beats = [t for t, i, _, d in frames[1:] if i == 0x701 and bytes(d) == b"\x7f"]
    assert len(frames) - 1 == len(beats)
    assert beats[0] == crossed(1.0, b"\x7f")
    assert len(beats) in (9, 10)


def test_each_bus_writes_its_own_trace(launch, connect, eds_files, tmp_path):
    """`trace` on each [[bus]]: every bus of the cell has its candump log, with its own frames."""
    from conftest import CHANNEL, HOST, free_port, wait_until
    port = free_port()
    a_log, b_log = tmp_path / "a.log", tmp_path / "b.log"
    cell = tmp_path / "two.toml"
    cell.write_text("\n".join([
        "[[bus]]", 'name = "a"', 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', f'trace = "{a_log}"', "",
        "[[bus]]", 'name = "b"', f'socketcand = "{HOST}:{port}"', f'channel = "{CHANNEL}"', f'trace = "{b_log}"', "",
        "[[drive]]", 'device = "cmmp-as"', "node = 1", 'bus = "a"', "",
        "[[drive]]", 'device = "testbench"', "node = 2", 'bus = "b"', "",
    ]))
    twin = launch(config=cell)
    wait_until(lambda: f"socketcand server on {HOST}:{port}, channel {CHANNEL}" in twin.stdout_lines,
               5.0, what="bus b's server")
    node = connect(twin).add_node(1, str(eds_files["cmmp-as"]))
    node.sdo.RESPONSE_TIMEOUT = 2.0
    node.sdo[0x6065].raw = 777
    other = connect(type("B", (), {"port": port})()).add_node(2, str(eds_files["testbench"]))
    other.sdo.RESPONSE_TIMEOUT = 2.0
    assert other.sdo[0x1017].raw == 0
    twin.stop()

    def ids(path):
        return {int(line.split()[2].split("#")[0], 16) for line in path.read_text().splitlines() if line}

    a_ids, b_ids = ids(a_log), ids(b_log)
    assert {0x601, 0x581, 0x701} <= a_ids and not {0x602, 0x582, 0x702} & a_ids, a_ids
    assert {0x602, 0x582, 0x702} <= b_ids and not {0x601, 0x581, 0x701} & b_ids, b_ids


def test_the_trace_of_a_timed_bus_has_its_load_beside_it(launch, tmp_path):
    """`trace` on a `[[bus]]` with a bit rate writes `<trace>.load.csv`, the bus load
    per 500 ms window; each window's load is the bit time (conftest.frame_bits) of the
    pcap's frames in it over its length, and tshark reads the pcap as before."""
    from conftest import CHANNEL

    bitrate = 125_000
    pcap = tmp_path / "bus.pcap"
    cell = tmp_path / "timed.toml"
    cell.write_text("\n".join([
        "[bus]", 'socketcand = "127.0.0.1:1"', f'channel = "{CHANNEL}"', f"bitrate = {bitrate}",
        f'trace = "{pcap}"', "",
        "[[drive]]", 'device = "cmmp-as"', "node = 1", "[drive.objects]", '"1017:00" = 10', "",
        "[[drive]]", 'device = "cmmp-as"', "node = 2", "[drive.objects]", '"1017:00" = 10', "",
    ]))
    twin = launch(config=cell)
    time.sleep(2.0)
    twin.stop()
    frames = read_pcap(pcap)
    lines = (tmp_path / "bus.pcap.load.csv").read_text().splitlines()
    assert lines[0] == (f"# drivetwin bus load: bitrate {bitrate} bit/s, window 500 ms, times in s "
                        "on the trace's clock"), lines[0]
    assert lines[1] == "end_s,window_s,load_percent,frames"
    rows = [l.split(",") for l in lines[2:]]
    assert len(rows) >= 2, lines
    start = frames[0][0]
    for end, window, load, count in rows:
        end, window, load, count = float(end), float(window), float(load), int(count)
        assert abs(window - (end - start)) < 2e-6, (start, end, window)
        inside = [f for f in frames if start - 1e-7 <= f[0] < end - 1e-7]
        assert len(inside) == count, (end, count, len(inside))
        bits = sum(frame_bits(i, bytes(d)) for _, i, _, d in inside)
        assert abs(load - bits / bitrate / window * 100) < 0.05, (load, bits, window)
        start = end
    # Two heartbeats every 10 ms at 125 kbit/s: about 9 % of the bus.
    assert 6 < float(rows[-1][2]) < 12, rows
    if shutil.which("tshark"):
        out = subprocess.run([shutil.which("tshark"), "-r", str(pcap), "-T", "fields", "-e", "can.id"],
                             capture_output=True, text=True, timeout=60)
        assert out.returncode == 0, out.stderr
        assert len(out.stdout.split()) == len(frames)
