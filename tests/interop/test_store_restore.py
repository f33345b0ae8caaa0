"""6. 1010h "save" / 1011h "load" across process restarts, CMMP-AS semantics: restore loads the
defaults into the current set and does not touch the stored set."""

import time

import can
import canopen
import pytest

from conftest import HeartbeatLog

LONG = "stored across restarts: " + "0123456789abcdef" * 40


def _state_files(d):
    return sorted(p.name for p in d.iterdir())


def test_store_survives_restart_and_restore_leaves_stored_set(launch, node_of, tmp_path):
    state = tmp_path / "state"
    twin = launch("testbench", 1, state_dir=state)
    node = node_of(twin)
    assert node.sdo[0x1017].raw == 1000, "commissioned heartbeat"
    node.sdo[0x1017].raw = 250
    node.sdo[0x2001].raw = LONG
    node.sdo[0x2003].raw = -77
    assert _state_files(state) == [], "nothing is written before a save"
    node.store()  # 1010h:01 = "save"
    files = _state_files(state)
    assert len(files) == 1 and not files[0].endswith(".tmp"), files
    assert (state / files[0]).stat().st_size > len(LONG)
    stored_text = (state / files[0]).read_bytes()
    twin.stop()
    assert _state_files(state) == files, "no temporary file left behind"
    assert (state / files[0]).read_bytes() == stored_text

    # a new process with the same state dir starts with the stored set
    twin.start()
    node = node_of(twin)
    assert node.sdo[0x1017].raw == 250
    assert node.sdo[0x2001].raw == LONG
    assert node.sdo[0x2003].raw == -77
    hb = HeartbeatLog(node)
    pos = hb.mark()
    hb.next_states(pos, 3, timeout=1.5)
    stamps = [t for t, _ in hb.states[pos:pos + 3]]
    assert stamps[-1] - stamps[0] < 0.9, "heartbeat runs at the stored 250 ms"

    # restore: the defaults come into the current set at once ...
    node.restore()  # 1011h:01 = "load"
    assert node.sdo[0x2001].raw == "drivetwin"
    assert node.sdo[0x2003].raw == 0
    assert node.sdo[0x1017].raw == 0, "1017h default of the test bench (heartbeat off)"
    # ... and the stored set is untouched
    assert _state_files(state) == files
    assert (state / files[0]).read_bytes() == stored_text
    twin.stop()

    # so without a new save, the next start brings the stored values back
    twin.start()
    node = node_of(twin)
    assert node.sdo[0x1017].raw == 250
    assert node.sdo[0x2001].raw == LONG
    assert node.sdo[0x2003].raw == -77


def test_restore_then_save_stores_the_defaults(launch, node_of, tmp_path):
    state = tmp_path / "state"
    twin = launch("testbench", 1, state_dir=state)
    node = node_of(twin)
    node.sdo[0x2001].raw = "first"
    node.store()
    node.restore()
    node.store()
    twin.stop()
    twin.start()
    node = node_of(twin)
    assert node.sdo[0x2001].raw == "drivetwin"


def test_cmmp_as_store_restart(launch, node_of, tmp_path):
    state = tmp_path / "state"
    twin = launch("cmmp-as", 1, state_dir=state)
    node = node_of(twin)
    node.sdo[0x1017].raw = 250
    node.store()
    assert not [p for p in state.iterdir() if p.name.endswith(".tmp")]
    twin.stop()
    twin.start()
    node = node_of(twin)
    assert node.sdo[0x1017].raw == 250
    # the identity is not a stored parameter and still reads the personality's values
    assert node.sdo[0x1018][1].raw == 0x1D


def test_save_repeatedly_leaves_only_complete_files(launch, node_of, tmp_path):
    state = tmp_path / "state"
    twin = launch("testbench", 1, state_dir=state)
    node = node_of(twin)
    for i in range(10):
        node.sdo[0x2001].raw = f"version {i} " + "x" * (i * 300)
        node.store()
        names = _state_files(state)
        assert len(names) == 1 and not any(n.endswith(".tmp") for n in names), names
    twin.stop()
    twin.start()
    node = node_of(twin)
    assert node.sdo[0x2001].raw == "version 9 " + "x" * 2700


# the client's receive thread sees the connection reset by the kill
@pytest.mark.filterwarnings("ignore::pytest.PytestUnhandledThreadExceptionWarning")
def test_kill_during_saves_leaves_an_old_or_new_set(launch, node_of, tmp_path):
    """SIGKILL while saves follow each other: the next start finds one complete stored set."""
    import threading

    import canopen

    state = tmp_path / "state"
    twin = launch("testbench", 1, state_dir=state)
    node = node_of(twin)
    node.sdo.RESPONSE_TIMEOUT = 1.0  # the request in flight at the kill waits this long
    versions = [f"v{i:03d}:" + chr(ord("a") + i % 26) * 3500 for i in range(200)]
    node.sdo[0x2001].raw = versions[0]
    node.store()
    written = []
    stop = threading.Event()

    def saver():
        for v in versions[1:]:
            if stop.is_set():
                return
            try:
                node.sdo[0x2001].raw = v
                node.store()
                written.append(v)
            except (canopen.SdoCommunicationError, canopen.SdoAbortedError, OSError, can.CanError):
                return

    t = threading.Thread(target=saver, daemon=True)
    t.start()
    deadline = time.monotonic() + 5
    while len(written) < 3 and time.monotonic() < deadline:
        time.sleep(0.01)
    twin.proc.kill()
    twin.proc.wait()
    stop.set()
    t.join(5)
    assert len(written) >= 3, "saves did not run"
    twin.start()
    node = node_of(twin)
    value = node.sdo[0x2001].raw
    assert value in versions, f"torn or unknown stored value: {value[:40]!r}..."
    # a save that was answered is durable
    assert versions.index(value) >= versions.index(written[-1]), (value[:5], written[-1][:5])


def test_failed_save_is_aborted(launch, node_of, tmp_path):
    state = tmp_path / "state"
    twin = launch("testbench", 1, state_dir=state)
    node = node_of(twin)
    node.sdo[0x2003].raw = 12
    # the state directory becomes unusable: a plain file in its place
    state.rmdir()
    state.write_text("not a directory")
    with pytest.raises(canopen.SdoAbortedError) as e:
        node.store()
    assert e.value.code in (0x06060000, 0x08000020)
