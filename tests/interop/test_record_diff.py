"""`drivetwin record` and `drivetwin diff` (docs/canopen.md "Record a drive, diff the twin"):
a script run against one twin, replayed against another; a twin with one object changed
differs exactly there, an identical twin not at all, and a committed recording of the default
cell still matches the twin.

Times are compared with a tolerance wide enough for a loaded machine and a bus at its real
bit rate: these tests are about which answers come, not how fast."""

import json
import re
import subprocess
from pathlib import Path

import can

from conftest import DRIVETWIN_BIN, free_port, recv_id, run_cli, write_cell

DATA = Path(__file__).resolve().parent / "data"
SCRIPT = DATA / "record_cmmp_as.toml"
RECORDING = DATA / "cmmp_as_recording.log"
TOLERANCE_MS = "250"
CHANGED = "6065:00"  # following error window


def _cell(tmp_path, name, objects):
    return write_cell(tmp_path / name, [("cmmp-as", 1, {"1017:00": 1000, **objects})])


def _record(twin, script, out):
    r = run_cli("record", str(script), "--socketcand", twin.addr, "-o", str(out))
    assert r.returncode == 0, r.stderr
    return out.read_text()


def _diff(recording, twin, *extra):
    return run_cli("diff", str(recording), "--socketcand", twin.addr,
                   "--time-tolerance", TOLERANCE_MS, *extra)


def test_a_twin_with_one_changed_object_differs_exactly_there(launch, tmp_path):
    recorded = launch(config=_cell(tmp_path, "a.toml", {}))
    changed = launch(config=_cell(tmp_path, "b.toml", {CHANGED: 5000}))
    same = launch(config=_cell(tmp_path, "c.toml", {}))
    rec = tmp_path / "a.log"
    _record(recorded, SCRIPT, rec)

    r = _diff(rec, changed)
    assert r.returncode == 1, (r.stdout, r.stderr)
    lines = r.stdout.strip().splitlines()
    assert lines and all(f"sdo read {CHANGED}" in l for l in lines), r.stdout
    # 5000 = 1388h, as the changed twin answers it
    assert "581#4365600088130000" in r.stdout, r.stdout
    assert "1 of" in r.stderr and "steps differ" in r.stderr, r.stderr

    r = _diff(rec, changed, "--json")
    assert r.returncode == 1, r.stderr
    report = json.loads(r.stdout)
    assert not report["equal"]
    assert [(d["label"], [x["kind"] for x in d["differences"]]) for d in report["differing"]] == [
        (f"sdo read {CHANGED}", ["bytes"])]

    replay = tmp_path / "c.log"
    r = _diff(rec, same, "-o", str(replay))
    assert r.returncode == 0, (r.stdout, r.stderr)
    assert "every answer equal" in r.stdout
    # the replay is a recording of its own: compared offline with the first, equal again
    r = run_cli("diff", str(rec), "--with", str(replay), "--time-tolerance", TOLERANCE_MS)
    assert r.returncode == 0, (r.stdout, r.stderr)


def test_the_committed_recording_of_the_default_cell_matches_the_twin(launch):
    twin = launch("cmmp-as", 1)
    r = _diff(RECORDING, twin)
    assert r.returncode == 0, (r.stdout, r.stderr)
    steps = sum(1 for l in RECORDING.read_text().splitlines() if l.startswith("# step "))
    assert r.stdout.strip().startswith(f"{steps} steps, every answer equal"), r.stdout


def test_a_recording_is_a_candump_log_python_can_reads(launch, tmp_path):
    twin = launch("cmmp-as", 1)
    text = _record(twin, SCRIPT, tmp_path / "r.log")
    plain = tmp_path / "plain.log"
    plain.write_text("".join(l + "\n" for l in text.splitlines() if not l.startswith("#")))
    msgs = list(can.CanutilsLogReader(str(plain)))
    assert {m.channel for m in msgs} == {"req", "ans"}
    # every SDO request has its response on 581h, the next answer after it
    for i, m in enumerate(msgs):
        if m.channel == "req" and m.arbitration_id == 0x601:
            answer = msgs[i + 1]
            assert (answer.channel, answer.arbitration_id) == ("ans", 0x581), answer
            assert answer.timestamp >= m.timestamp
    identity = [m for m in msgs if m.arbitration_id == 0x581 and m.data[1:4] == bytes([0x18, 0x10, 1])]
    assert bytes(identity[0].data[4:8]) == (0x1D).to_bytes(4, "little")  # Festo
    # the NMT start is answered by an operational heartbeat, the reset by the boot-up
    hb = [bytes(m.data) for m in msgs if m.arbitration_id == 0x701]
    assert hb == [b"\x05", b"\x00"], hb


def test_an_answer_later_than_the_tolerance_differs(tmp_path):
    text = RECORDING.read_text()
    lines = text.splitlines()
    # the answer to `sdo read 1018:01`, 100 ms later
    step = next(i for i, l in enumerate(lines) if l.startswith("# step ") and "sdo read 1018:01" in l)
    answer = step + 2
    m = re.match(r"\((\d+)\.(\d{6})\) ans (.*)", lines[answer])
    assert m, lines[answer]
    t = int(m.group(1)) * 1_000_000 + int(m.group(2)) + 100_000
    lines[answer] = f"({t // 1_000_000}.{t % 1_000_000:06d}) ans {m.group(3)}"
    late = tmp_path / "late.log"
    late.write_text("\n".join(lines) + "\n")

    r = run_cli("diff", str(RECORDING), "--with", str(late), "--time-tolerance", "50")
    assert r.returncode == 1, (r.stdout, r.stderr)
    out = r.stdout.strip().splitlines()
    assert len(out) == 1 and "sdo read 1018:01" in out[0] and "time" in out[0], r.stdout
    r = run_cli("diff", str(RECORDING), "--with", str(late), "--time-tolerance", "150")
    assert r.returncode == 0, (r.stdout, r.stderr)


def test_a_candump_log_is_a_script_of_its_master_frames(launch, tmp_path):
    twin = launch("cmmp-as", 1)
    text = _record(twin, DATA / "sdo_session.log", tmp_path / "r.log")
    reqs = [l.split()[2] for l in text.splitlines() if " req " in l]
    assert reqs == ["601#4000100000000000", "601#4018100100000000", "601#2B40600006000000",
                    "601#4041600000000000"], text
    answers = [l.split()[2] for l in text.splitlines() if " ans " in l]
    assert answers[:3] == ["581#4300100092010200", "581#431810011D000000", "581#6040600000000000"]


def test_bad_input_exits_2_naming_file_and_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[[step]]\nread = "1018:01"\n\n[[step]]\nread = "1018"\n')
    r = run_cli("record", str(bad), "--socketcand", f"127.0.0.1:{free_port()}")
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert f"{bad}:4:" in r.stderr and "IIII:SS" in r.stderr, r.stderr

    r = run_cli("diff", str(tmp_path / "missing.log"))
    assert r.returncode == 2, r.stderr
    garbage = tmp_path / "garbage.log"
    garbage.write_text(RECORDING.read_text().replace(" ans 581#4300", " xyz 581#4300"))
    r = run_cli("diff", str(garbage), "--with", str(RECORDING))
    assert r.returncode == 2 and f"{garbage}:8:" in r.stderr, r.stderr
    # nobody listens: an I/O error is 2 as well, not "different"
    r = run_cli("diff", str(RECORDING), "--socketcand", f"127.0.0.1:{free_port()}")
    assert r.returncode == 2, (r.stdout, r.stderr)
    r = run_cli("diff", str(RECORDING), "--with", str(RECORDING), "--time-tolerance", "-1")
    assert r.returncode == 2, r.stderr


def test_a_syncs_answer_is_the_tpdo_and_a_changed_mapped_object_differs_there(launch, tmp_path):
    recorded = launch(config=_cell(tmp_path, "a.toml", {}))
    changed = launch(config=_cell(tmp_path, "b.toml", {CHANGED: 5000}))
    same = launch(config=_cell(tmp_path, "c.toml", {}))
    rec = tmp_path / "a.log"
    text = _record(recorded, DATA / "record_pdo.toml", rec)
    sync = text.split(": SYNC (line")[1]
    # the statusword, then the following error window: 9101 (238Dh), the default
    assert re.search(r" ans 181#[0-9A-F]{4}8D230000\n", sync.split("# step")[0]), text

    r = _diff(rec, changed, "--json")
    assert r.returncode == 1, (r.stdout, r.stderr)
    report = json.loads(r.stdout)
    assert [(d["label"], [x["kind"] for x in d["differences"]]) for d in report["differing"]] == [
        ("SYNC", ["bytes"])], report
    assert re.search(r"replayed 181#[0-9A-F]{4}88130000", report["differing"][0]["differences"][0]["text"])

    r = _diff(rec, same)
    assert r.returncode == 0, (r.stdout, r.stderr)


def test_a_link_lost_halfway_leaves_the_steps_run_so_far(launch, raw_bus, tmp_path):
    twin = launch("cmmp-as", 1)
    script = tmp_path / "s.toml"
    # node 5 is absent: its read waits 20 s, long enough to stop the twin under it
    script.write_text('[[step]]\nread = "1018:01"\n\n[[step]]\nread = "1018:01"\nnode = 5\n'
                      'wait_ms = 20000\n')
    out = tmp_path / "r.log"
    bus = raw_bus(twin)
    proc = subprocess.Popen([str(DRIVETWIN_BIN), "record", str(script), "--socketcand", twin.addr,
                             "-o", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert recv_id(bus, 0x605, timeout=10.0) is not None, "the second request never came"
        bus.shutdown()
        twin.stop()
        _, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 3, err  # the bus connection
    text = out.read_text()
    assert "# cut short: the bus connection was closed" in text, text
    assert " ans 581#431810011D000000" in text and " req 605#4018100100000000" in text, text
