"""The short form of the cell FMU's speed benchmark (scripts/fmu_speed.py,
docs/performance.md): the ten-drive cell 0.2 s as an FMU stepped by fmpy at 1 ms and natively
(`drivetwin run --virtual-seconds`); the script runs and prints the speeds and the ratios.
The figures themselves are measured with the full form on a quiet machine."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from conftest import DRIVETWIN_BIN, REPO_ROOT

pytest.importorskip("fmpy")


def test_the_speed_script_prints_both_speeds_and_the_ratio(cell_library):
    # The script packs the cell with the binary, which takes the library beside it.
    out = subprocess.run(
        [sys.executable, str(REPO_ROOT / "scripts" / "fmu_speed.py"), "--seconds", "0.2",
         "--binary", str(DRIVETWIN_BIN)],
        check=True, capture_output=True, text=True, cwd=REPO_ROOT, timeout=300,
    ).stdout
    assert re.search(r"^native .* ([0-9.]+)x real time$", out, re.M), out
    ratios = re.findall(r"([0-9.]+) % of native$", out, re.M)
    # simulate_fmu as called, its stepping loop alone, with one output, doStep with every output
    # read (the low-level getters, fmpy's getters), doStep.
    assert len(ratios) == 6 and all(float(r) > 0 for r in ratios), out
