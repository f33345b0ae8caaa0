"""Scenarios in CI: `drivetwin scenario FILE` as a subprocess on the
virtual clock. The passing example (a limit switch and a broken cable leading to the drive's
fault and the EMCYs) exits 0 and prints the same report and writes the same trace twice; the
one meant to fail exits 1 and names the expectation it missed; a bad file is a usage error."""

from __future__ import annotations

import json

from conftest import REPO_ROOT, run_cli

EXAMPLES = REPO_ROOT / "examples" / "scenarios"


def test_the_passing_scenario_exits_0_with_the_same_report_and_trace_twice(tmp_path):
    runs = []
    for i in range(2):
        trace = tmp_path / f"run{i}.pcap"
        r = run_cli("scenario", str(EXAMPLES / "limit_switch.toml"), "--trace", str(trace),
                    timeout=120)
        assert r.returncode == 0, (r.stdout, r.stderr)
        runs.append((r.stdout, trace.read_bytes()))
    (report, trace_a), (again, trace_b) = runs
    assert report == again
    assert trace_a == trace_b, "the traces are equal bit for bit"
    assert trace_a[:4] == bytes.fromhex("d4c3b2a1"), "a pcap"
    lines = report.splitlines()
    assert lines[0].startswith("scenario limit switch and broken cable: PASS (6 of 6")
    for name in ("the limit switch faults the drive", "the drive reports the limit switch",
                 "node 2 misses node 1's heartbeat"):
        assert any(l.startswith(f"  PASS  {name}: met at ") for l in lines), (name, report)


def test_the_scenario_meant_to_fail_exits_1_naming_its_expectation():
    r = run_cli("scenario", str(EXAMPLES / "must_fail.toml"), timeout=120)
    assert r.returncode == 1, (r.stdout, r.stderr)
    name = "the drive stays enabled with its limit switch closed"
    assert f"  FAIL  {name}: not met from 0.350000s to 0.450000s" in r.stdout, r.stdout
    assert "  PASS  the drive is enabled: met at " in r.stdout
    assert f"error: scenario failed: {name}" in r.stderr


def test_the_report_as_json():
    r = run_cli("scenario", str(EXAMPLES / "must_fail.toml"), "--json", timeout=120)
    assert r.returncode == 1
    report = json.loads(r.stdout)
    assert report["passed"] is False
    failed = [o["name"] for o in report["expectations"] if not o["passed"]]
    assert failed == ["the drive stays enabled with its limit switch closed"]


def test_a_bad_scenario_is_a_usage_error_naming_its_step(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[cell]\n[[cell.drive]]\ndevice = "cmmp-as"\nnode = 1\n\n'
                   '[[step]]\nat = "1s"\nexpect_state = "dancing"\n')
    r = run_cli("scenario", str(bad))
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert "step 1 (at 1000ms)" in r.stderr and "operation enabled" in r.stderr, r.stderr
    r = run_cli("scenario", str(tmp_path / "missing.toml"))
    assert r.returncode == 2
    assert "missing.toml" in r.stderr


def test_every_other_example_passes():
    for path in sorted(EXAMPLES.glob("*.toml")):
        if path.name == "must_fail.toml":
            continue
        r = run_cli("scenario", str(path), timeout=120)
        assert r.returncode == 0, (path.name, r.stdout, r.stderr)
        assert ": PASS (" in r.stdout.splitlines()[0]
