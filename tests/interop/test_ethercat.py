"""The twin as an EtherCAT slave, driven by SOEM (PyPI `pysoem`) over a veth pair.

`drivetwin run --ethercat dtwA` runs inside a private network namespace on one end of a veth
pair; pysoem opens the other end in the test's namespace: `config_init` finds one slave with
Festo's identity, SDO read and write over CoE work, `config_map` reads the PDO assignment and
mapping over CoE (1C12h/1C13h, 1600h/1A00h), the slave goes to Safe-Op and Op, and a cyclic
1 kHz loop enables the CiA 402 drive (controlword 6 → 7 → Fh, statusword → 0x27) with the
working counter checked on every cycle.

Needs root (network namespaces, raw sockets) and `ip` (iproute2); skips with a message
otherwise. ETHERCAT_CYCLIC_SECONDS sets the length of the cyclic run (default 2 s; an
acceptance run is 10 s or more: `ETHERCAT_CYCLIC_SECONDS=10 pytest ...`); the CSP
session runs ETHERCAT_CSP_SECONDS (default 10 s, an acceptance run). A third test runs the drive on
DC SYNC0 (10 ms) and stops the master to provoke the synchronisation error.
"""

from __future__ import annotations

import os
import shutil
import signal
import struct
import subprocess
import time

import pytest

from conftest import Realtime, ecat_twin_run, product_code

pysoem = pytest.importorskip("pysoem", reason="pysoem is not installed (pip install pysoem)")

CYCLIC_SECONDS = float(os.environ.get("ETHERCAT_CYCLIC_SECONDS", "2"))
# The CSP session: an acceptance run, 10 s at 1 kHz.
CSP_SECONDS = float(os.environ.get("ETHERCAT_CSP_SECONDS", "10"))
CYCLE_S = 0.001
FESTO = 0x1D


@pytest.fixture
def ecat_twin(veth, tmp_path):
    with ecat_twin_run(veth, tmp_path) as twin:
        yield twin


@pytest.fixture
def ecat_chain(veth, tmp_path):
    """Two CMMP-AS in one chain (a cell file with two drives), the frame thread spinning on
    the socket (--busy-poll)."""
    cell = tmp_path / "chain.toml"
    cell.write_text('[[drive]]\ndevice = "cmmp-as"\nnode = 1\n\n[[drive]]\ndevice = "cmmp-as"\nnode = 2\n')
    with ecat_twin_run(veth, tmp_path, "--config", str(cell), "--busy-poll", slaves=2) as twin:
        yield twin


DC_CYCLE_NS = 10_000_000


@pytest.fixture
def ecat_twin_10ms(veth, tmp_path):
    """A CMMP-AS whose interpolator cycle 60C2h is commissioned to 10 ms (a cycle a Python
    loop keeps even on a loaded machine)."""
    cell = tmp_path / "cell.toml"
    cell.write_text('[[drive]]\ndevice = "cmmp-as"\nnode = 1\n[drive.objects]\n"60C2:01" = 10\n')
    with ecat_twin_run(veth, tmp_path, "--config", str(cell), realtime=True) as twin:
        yield twin


def _wait_cycle(due: float) -> float:
    """Sleeps until `due`; a master that fell behind (the machine held it off the CPU) drops
    the cycles it missed instead of sending them in a burst, as a real-time master would."""
    delay = due - time.monotonic()
    if delay > 0:
        time.sleep(delay)
        return due
    return time.monotonic()


def _assign_csp_pdos(slave) -> None:
    """RxPDO3 (controlword + target position, 1602h) and TxPDO3 (statusword + position
    actual, 1A02h) assigned over CoE in Pre-Op, and CSP (6060h = 8, EtherCAT only)."""
    for index, pdo in ((0x1C12, 0x1602), (0x1C13, 0x1A02)):
        slave.sdo_write(index, 0, bytes([0]))
        slave.sdo_write(index, 1, struct.pack("<H", pdo))
        slave.sdo_write(index, 0, bytes([1]))
    slave.sdo_write(0x6060, 0, bytes([8]))


def _csp_cycle(master, slave):
    """One process-data cycle of the CSP layout: (working counter, statusword, position)."""
    def cycle(cw, target):
        slave.output = struct.pack("<Hi", cw, target)
        master.send_processdata()
        wkc = master.receive_processdata(100_000)
        sw, pos = struct.unpack("<Hi", bytes(slave.input))
        return wkc, sw, pos
    return cycle


def _csp_to_op(master, slave, cycle, cycle_s) -> int:
    """Requests Op while cycling (as SOEM's examples do); returns the actual position."""
    master.state = pysoem.OP_STATE
    _, _, pos = cycle(0, 0)
    master.write_state()
    for _ in range(200):
        _, _, pos = cycle(0, pos)
        if master.read_state() == pysoem.OP_STATE:
            break
        time.sleep(cycle_s)
    assert slave.state == pysoem.OP_STATE, f"Op: {slave.state:#x} code {slave.al_status:#x}"
    return pos


def _state_ok(master, state, timeout_us=2_000_000) -> bool:
    return master.state_check(state, timeout_us) == state


def test_soem_finds_maps_and_enables_the_drive(ecat_twin):
    master_if, banner = ecat_twin
    master = pysoem.Master()
    master.open(master_if)
    try:
        assert master.config_init() == 1, "one slave on the wire"
        slave = master.slaves[0]
        assert slave.man == FESTO
        assert slave.id == product_code()
        assert "CMMP" in slave.name, slave.name

        # SDO over CoE in Pre-Op.
        assert int.from_bytes(slave.sdo_read(0x1018, 1), "little") == FESTO
        slave.sdo_write(0x6065, 0, (12345).to_bytes(4, "little"))  # following error window
        assert int.from_bytes(slave.sdo_read(0x6065, 0), "little") == 12345
        with pytest.raises(pysoem.SdoError):
            slave.sdo_read(0x5FFF, 0)  # no such object: abort 0602 0000h

        # SOEM reads 1C12h/1C13h and the mapping objects over CoE.
        size = master.config_map()
        assert (len(slave.output), len(slave.input)) == (2, 2), "controlword / statusword"
        assert size == 4
        assert _state_ok(master, pysoem.SAFEOP_STATE), f"Safe-Op: AL status code {slave.al_status:#x}"
        assert master.expected_wkc == 3

        master.state = pysoem.OP_STATE
        # Outputs before and while Op is requested, as SOEM's examples do.
        master.send_processdata()
        master.receive_processdata(2000)
        master.write_state()
        for _ in range(200):
            master.send_processdata()
            master.receive_processdata(2000)
            if master.read_state() == pysoem.OP_STATE:
                break
            time.sleep(CYCLE_S)
        assert slave.state == pysoem.OP_STATE, f"Op: state {slave.state:#x} code {slave.al_status:#x}"

        sequence = [0x0006, 0x0007, 0x000F]
        expect = {0x0006: 0x21, 0x0007: 0x23, 0x000F: 0x27}
        step = 0
        enabled_at = None
        cycles = bad_wkc = 0
        sw = 0
        end = time.monotonic() + CYCLIC_SECONDS
        next_cycle = time.monotonic()
        while time.monotonic() < end:
            cw = sequence[step]
            slave.output = cw.to_bytes(2, "little")
            master.send_processdata()
            # 100 ms: the twin answers in well under a millisecond, but a shared CI machine can
            # hold either process off the CPU for a while; a frame that never comes back
            # still counts as a wrong working counter.
            wkc = master.receive_processdata(100_000)
            cycles += 1
            if wkc != master.expected_wkc:
                bad_wkc += 1
            sw = int.from_bytes(slave.input[:2], "little")
            if sw & 0x6F == expect[cw] and step < len(sequence) - 1:
                step += 1
            elif sw & 0x6F == 0x27 and enabled_at is None:
                enabled_at = cycles
            next_cycle = _wait_cycle(next_cycle + CYCLE_S)
        print(f"{cycles} cycles in {CYCLIC_SECONDS} s, enabled after {enabled_at}, statusword {sw:#06x}")
        assert bad_wkc == 0, f"{bad_wkc} of {cycles} cycles with a wrong working counter"
        assert enabled_at is not None, f"never OPERATION ENABLED: statusword {sw:#06x}"
        assert sw & 0x6F == 0x27, f"statusword {sw:#06x} at the end"
        assert cycles >= CYCLIC_SECONDS * 200, f"only {cycles} cycles in {CYCLIC_SECONDS} s"

        master.state = pysoem.INIT_STATE
        master.write_state()
        assert _state_ok(master, pysoem.INIT_STATE)
    finally:
        master.close()


def test_csp_session_follows_the_commanded_path(ecat_twin):
    """Cyclic synchronous position: the master sends a target every 1 ms cycle through RxPDO3
    (controlword + target position, 1602h) and reads TxPDO3 (statusword + position actual,
    1A02h); the simulated axis follows the ramp with a small lag and the working counter is
    right on every cycle."""
    master_if, _ = ecat_twin
    master = pysoem.Master()
    master.open(master_if)
    try:
        assert master.config_init() == 1
        slave = master.slaves[0]
        _assign_csp_pdos(slave)
        assert master.config_map() == 12
        assert (len(slave.output), len(slave.input)) == (6, 6)
        assert _state_ok(master, pysoem.SAFEOP_STATE), f"Safe-Op: AL status code {slave.al_status:#x}"

        cycle = _csp_cycle(master, slave)
        pos = _csp_to_op(master, slave, cycle, CYCLE_S)

        bad_wkc = 0
        target = pos
        for cw, want in ((0x06, 0x21), (0x07, 0x23), (0x0F, 0x27)):
            for _ in range(400):
                wkc, sw, pos = cycle(cw, target)
                bad_wkc += wkc != master.expected_wkc
                if sw & 0x6F == want:
                    break
                time.sleep(CYCLE_S)
            assert sw & 0x6F == want, f"statusword {sw:#06x} waiting for {want:#x}"
        assert int.from_bytes(slave.sdo_read(0x6061, 0), "little", signed=True) == 8

        # A ramp at 300 rpm (65536 × 300 / 60 / 1000 = 327 increments per ms) for
        # ETHERCAT_CSP_SECONDS (at least 1 s), then 0.3 s of holding.
        step = 327
        ramp = max(1000, int(CSP_SECONDS * 1000))
        max_lag = 0
        start = target
        next_cycle = time.monotonic()
        for n in range(ramp + 300):
            if n < ramp:
                target += step
            wkc, sw, pos = cycle(0x0F, target)
            bad_wkc += wkc != master.expected_wkc
            max_lag = max(max_lag, abs(target - pos))
            next_cycle = _wait_cycle(next_cycle + CYCLE_S)
        print(f"CSP: moved {pos - start} increments, max lag {max_lag}, statusword {sw:#06x}")
        assert bad_wkc == 0
        assert sw & 0x6F == 0x27, f"still enabled: {sw:#06x}"
        assert abs(pos - target) < 100, f"stands at the last set-point: {pos} vs {target}"
        # The lag stays well inside the default following-error window (6065h = 9101).
        assert max_lag < 9101, max_lag
        assert pos - start > ramp * step - 100
    finally:
        master.close()


def test_dc_sync0_drives_the_cycle_and_a_stopped_master_is_a_sync_error(ecat_twin_10ms):
    """Distributed clocks: SOEM's config_dc / dc_sync. A SYNC0 cycle other than the
    interpolator cycle (60C2h) is refused on Pre-Op → Safe-Op with AL status code 0x0036; with
    the right one the drive runs on SYNC0, PDO configuration writes are refused outside Pre-Op
    (abort 0800 0022h), and when the master stops sending the slave falls back to Safe-Op with
    0x001A and the drive reports the error. Master and twin run at SCHED_FIFO where allowed,
    as a DC master and a drive's firmware do."""
    master_if, _ = ecat_twin_10ms
    master = pysoem.Master()
    master.open(master_if)
    try:
        with Realtime():
            _dc_session(master)
    finally:
        master.close()


def _dc_session(master):
    assert master.config_init() == 1
    slave = master.slaves[0]
    assert slave.sdo_read(0x60C2, 1)[0] == 10, "interpolator cycle 10 ms"
    _assign_csp_pdos(slave)
    assert master.config_dc(), "the twin has distributed clocks"
    # SYNC0 at 1 ms against a 10 ms interpolator: SOEM's config_map requests Safe-Op,
    # which is refused.
    slave.dc_sync(True, 1_000_000)
    assert master.config_map() == 12
    master.state_check(pysoem.SAFEOP_STATE, 1_000_000)
    master.read_state()
    assert slave.state == pysoem.PREOP_STATE | pysoem.STATE_ERROR, f"{slave.state:#x}"
    assert slave.al_status == 0x0036, f"AL status code {slave.al_status:#x}"
    slave.state = pysoem.PREOP_STATE | pysoem.STATE_ACK
    slave.write_state()
    assert _state_ok(master, pysoem.PREOP_STATE)

    slave.dc_sync(True, DC_CYCLE_NS)
    slave.state = pysoem.SAFEOP_STATE
    slave.write_state()
    assert _state_ok(master, pysoem.SAFEOP_STATE), f"Safe-Op: AL status code {slave.al_status:#x}"

    cycle_s = DC_CYCLE_NS / 1e9
    cycle = _csp_cycle(master, slave)
    pos = _csp_to_op(master, slave, cycle, cycle_s)

    # In Op the PDO assignment is locked.
    with pytest.raises(pysoem.SdoError) as err:
        slave.sdo_write(0x1C12, 0, bytes([0]))
    assert err.value.abort_code == 0x0800_0022, hex(err.value.abort_code)

    target = pos
    bad_wkc = 0
    sw = 0
    next_cycle = time.monotonic()
    for cw, want in ((0x06, 0x21), (0x07, 0x23), (0x0F, 0x27)):
        for _ in range(100):
            wkc, sw, pos = cycle(cw, target)
            bad_wkc += wkc != master.expected_wkc
            if sw & 0x6F == want:
                break
            next_cycle = _wait_cycle(next_cycle + cycle_s)
        assert sw & 0x6F == want, f"statusword {sw:#06x} waiting for {want:#x}"
    # One second of CSP on SYNC0: 100 targets, 1000 increments apart.
    for _ in range(100):
        target += 1000
        wkc, sw, pos = cycle(0x0F, target)
        bad_wkc += wkc != master.expected_wkc
        next_cycle = _wait_cycle(next_cycle + cycle_s)
    for _ in range(30):
        wkc, sw, pos = cycle(0x0F, target)
        next_cycle = _wait_cycle(next_cycle + cycle_s)
    assert bad_wkc == 0
    assert sw & 0x6F == 0x27, f"enabled on SYNC0: {sw:#06x}"
    assert abs(pos - target) < 100, f"followed the targets: {pos} vs {target}"
    assert master.read_state() == pysoem.OP_STATE, f"no sync error while cycling: {slave.al_status:#x}"

    # The master stops for 0.2 s (20 SYNC0 cycles): synchronisation error.
    time.sleep(0.2)
    master.read_state()
    assert slave.state == pysoem.SAFEOP_STATE | pysoem.STATE_ERROR, f"{slave.state:#x}"
    assert slave.al_status == 0x001A, f"AL status code {slave.al_status:#x}"
    # The drive's error comes as a CoE emergency: 63-4 with code 8781h, register 11h.
    emergencies = []
    slave.add_emergency_callback(emergencies.append)
    sw = int.from_bytes(slave.sdo_read(0x6041, 0), "little")
    assert sw & 0x08, f"the drive reports the error: statusword {sw:#06x}"
    assert [(e.error_code, e.error_reg) for e in emergencies] == [(0x8781, 0x11)], emergencies


def test_a_chain_of_two_slaves_runs_in_op(ecat_chain):
    """The frame passes through both slaves in order: SOEM counts two, gives each its station
    address, maps both, and every cycle's working counter counts both (2 × (outputs 2 +
    inputs 1))."""
    master_if, _ = ecat_chain
    master = pysoem.Master()
    master.open(master_if)
    try:
        assert master.config_init() == 2, "two slaves on the wire"
        assert [s.man for s in master.slaves] == [FESTO, FESTO]
        # Each answers its own SDOs: a value written to the second is not in the first.
        master.slaves[1].sdo_write(0x6065, 0, (4321).to_bytes(4, "little"))
        assert int.from_bytes(master.slaves[1].sdo_read(0x6065, 0), "little") == 4321
        assert int.from_bytes(master.slaves[0].sdo_read(0x6065, 0), "little") != 4321
        assert master.config_map() == 8
        assert _state_ok(master, pysoem.SAFEOP_STATE)
        assert master.expected_wkc == 6
        master.state = pysoem.OP_STATE
        master.send_processdata()
        master.receive_processdata(100_000)
        master.write_state()
        for _ in range(200):
            master.send_processdata()
            master.receive_processdata(100_000)
            if master.read_state() == pysoem.OP_STATE:
                break
            time.sleep(CYCLE_S)
        assert [s.state for s in master.slaves] == [pysoem.OP_STATE] * 2
        # Enable only the second drive: the outputs land in the right slave.
        sw = [0, 0]
        bad_wkc = 0
        for cw in (0x06, 0x07, 0x0F):
            for _ in range(200):
                master.slaves[0].output = (0).to_bytes(2, "little")
                master.slaves[1].output = cw.to_bytes(2, "little")
                master.send_processdata()
                bad_wkc += master.receive_processdata(100_000) != master.expected_wkc
                sw = [int.from_bytes(s.input[:2], "little") for s in master.slaves]
                if sw[1] & 0x6F == {0x06: 0x21, 0x07: 0x23, 0x0F: 0x27}[cw]:
                    break
                time.sleep(CYCLE_S)
        assert bad_wkc == 0
        assert sw[1] & 0x6F == 0x27, f"second drive enabled: {sw[1]:#06x}"
        assert sw[0] & 0x4F == 0x40, f"first drive untouched: {sw[0]:#06x}"
    finally:
        master.close()


def test_tshark_decodes_a_capture_as_ethercat_and_coe(ecat_twin, tmp_path):
    tshark = shutil.which("tshark")
    if tshark is None:
        pytest.skip("tshark (Debian package tshark) is not installed")
    master_if, _ = ecat_twin
    cap = tmp_path / "ecat.pcap"
    dump = subprocess.Popen([tshark, "-i", master_if, "-w", str(cap), "-q"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        # tshark says "Capturing on 'IF'" once it captures (seconds on a loaded machine).
        deadline = time.monotonic() + 60
        started = ""
        while "Capturing on" not in started and time.monotonic() < deadline:
            line = dump.stderr.readline().decode(errors="replace")
            if not line:
                break
            started += line
        assert "Capturing on" in started, f"tshark did not start: {started}"
        time.sleep(0.2)
        master = pysoem.Master()
        master.open(master_if)
        try:
            assert master.config_init() == 1
            assert int.from_bytes(master.slaves[0].sdo_read(0x1018, 1), "little") == FESTO
            master.config_map()
            assert _state_ok(master, pysoem.SAFEOP_STATE)
        finally:
            master.close()
        time.sleep(0.5)
    finally:
        dump.send_signal(signal.SIGINT)
        dump.wait(10)
    out = subprocess.run([tshark, "-r", str(cap), "-V"], capture_output=True, text=True,
                         timeout=60).stdout
    assert "EtherCAT frame header" in out, out[:2000]
    assert "EtherCAT datagram" in out
    assert "Working Cnt" in out
    # The SDO read of 1018h:01 as a CoE mailbox exchange.
    assert "CoE" in out or "CANopen" in out, "no CoE mailbox decoded"
    assert "0x1018" in out.lower() or "1018" in out


def test_run_trace_records_the_session_as_ethercat(veth, tmp_path):
    """`drivetwin run --ethercat IF --trace F.pcap`: every frame in and out, decoded by tshark
    as EtherCAT datagrams with the CoE exchange of an SDO read."""
    tshark = shutil.which("tshark")
    if tshark is None:
        pytest.skip("tshark (Debian package tshark) is not installed")
    trace = tmp_path / "twin.pcap"
    # Leaving the block stops the twin, which flushes the trace.
    with ecat_twin_run(veth, tmp_path, "--trace", str(trace)) as (master_if, banner):
        assert any("tracing to" in l for l in banner), banner
        master = pysoem.Master()
        master.open(master_if)
        try:
            assert master.config_init() == 1
            assert int.from_bytes(master.slaves[0].sdo_read(0x1018, 1), "little") == FESTO
        finally:
            master.close()
    out = subprocess.run([tshark, "-r", str(trace), "-V"], capture_output=True, text=True,
                         timeout=60).stdout
    assert "EtherCAT frame header" in out, out[:2000]
    assert "Working Cnt" in out
    assert "CoE" in out or "CANopen" in out, "no CoE mailbox decoded"
    frames = subprocess.run([tshark, "-r", str(trace), "-T", "fields", "-e", "eth.type"],
                            capture_output=True, text=True, timeout=60).stdout.split()
    assert len(frames) >= 20 and set(frames) == {"0x88a4"}, frames[:10]
    # Requests and replies: the replies carry the returned-frame bit in the source MAC.
    sources = subprocess.run([tshark, "-r", str(trace), "-T", "fields", "-e", "eth.src"],
                             capture_output=True, text=True, timeout=60).stdout.split()
    assert any(s.startswith("03:") for s in sources) and any(not s.startswith("03:") for s in sources)



def _raw_frame(payload: bytes) -> bytes:
    """Broadcast Ethernet frame with EtherType 88A4h from SOEM's source MAC (the slave marks a
    processed frame by setting bit 1 of the source's first byte)."""
    return b"\xff" * 6 + b"\x01" * 6 + b"\x88\xa4" + payload


def _ecat_header(length: int) -> bytes:
    return (length | (1 << 12)).to_bytes(2, "little")


def test_bad_frames_are_dropped_and_the_slave_goes_on(ecat_twin):
    """Truncated frames, a datagram past the frame end, a length field beyond the frame,
    unknown commands and a datagram for a missing station, straight from a raw socket: the
    twin drops or skips them and SOEM finds it afterwards as before."""
    import socket

    master_if, _ = ecat_twin
    sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(0x88A4))
    sock.bind((master_if, 0))
    brd = bytes([0x07, 0x00, 0, 0, 0, 0, 0x02, 0x00, 0, 0]) + b"\x00\x00" + b"\x00\x00"  # BRD 0x0000
    bad = [
        _raw_frame(b""),                                   # no EtherCAT header
        _raw_frame(b"\x0e"),                               # half a header
        _raw_frame(_ecat_header(40) + brd),                # header says more than there is
        _raw_frame(_ecat_header(len(brd)) + brd[:9]),      # datagram cut in its header
        _raw_frame(_ecat_header(len(brd)) + bytes([0x07, 0, 0, 0, 0, 0, 0xF0, 0x07, 0, 0])),
        _raw_frame(_ecat_header(14) + bytes([0x77]) + brd[1:]),   # unknown command 77h
        _raw_frame(_ecat_header(14) + bytes([0x04, 0, 0x34, 0x12]) + brd[4:]),  # FPRD, no such station
        _raw_frame(bytes(range(256)) * 5),                 # garbage
    ]
    try:
        for _ in range(20):
            for f in bad:
                sock.send(f.ljust(60, b"\x00"))
        # A good BRD still counts one slave.
        sock.settimeout(2)
        sock.send(_raw_frame(_ecat_header(len(brd)) + brd).ljust(60, b"\x00"))
        deadline = time.monotonic() + 2
        wkc = None
        while time.monotonic() < deadline:
            data = sock.recv(1514)
            if data[6] & 0x02 and len(data) >= 30 and data[16] == 0x07:  # returned BRD
                wkc = int.from_bytes(data[14 + 2 + 10 + 2:14 + 2 + 10 + 4], "little")
                break
        assert wkc == 1, f"BRD after the bad frames: wkc {wkc}"
    finally:
        sock.close()
    master = pysoem.Master()
    master.open(master_if)
    try:
        assert master.config_init() == 1, "the slave goes on"
        assert int.from_bytes(master.slaves[0].sdo_read(0x1018, 1), "little") == FESTO
    finally:
        master.close()


def test_save_over_coe_survives_a_restart_with_a_state_dir(veth, tmp_path):
    """1010h:01 "save" over CoE writes the drive's parameter file (--state-dir) before its
    answer; the next start of the chain powers on with the saved value."""
    state = tmp_path / "state"
    twin = ecat_twin_run

    def session(action):
        with twin(veth, tmp_path, "--state-dir", str(state)) as (master_if, _):
            master = pysoem.Master()
            master.open(master_if)
            try:
                assert master.config_init() == 1
                return action(master.slaves[0])
            finally:
                master.close()

    def write_and_save(slave):
        slave.sdo_write(0x6065, 0, (54321).to_bytes(4, "little"))  # following error window
        slave.sdo_write(0x1010, 1, b"save")

    session(write_and_save)
    assert (state / "cmmp-as-node1.params").exists()
    window = session(lambda slave: int.from_bytes(slave.sdo_read(0x6065, 0), "little"))
    assert window == 54321, "the saved value after the restart"
