#!/usr/bin/env python3
"""The virtual-time speed of a cell as an FMU stepped by fmpy at 1 ms, against the same cell's
own run on the virtual clock (`drivetwin run --config CELL --virtual-seconds T`): both speeds
(virtual seconds per wall second) and their ratio (docs/performance.md, "The cell as an FMU").

    scripts/cell-fmu && python3 scripts/fmu_speed.py                 # 10 s of the ten-drive cell
    python3 scripts/fmu_speed.py --seconds 1 --cell examples/cell_fmu/ten_drives.toml

The FMU is packed from the cell by the release binary (`target/release/drivetwin fmu`). fmpy
steps it four ways:

- `fmpy.simulate_fmu` on the `.fmu` (every output recorded at every step, as a user's
  simulation does: the archive extracted, its description read and validated, then stepped);
- `fmpy.simulate_fmu` on the extracted FMU with its description read beforehand and without
  validation (the stepping loop and fmpy's recorder alone);
- the same with `output=` one variable (the first drive's position): fmpy's loop with the
  least recording an importer can ask for;
- the low-level FMI 3 API, `fmi3DoStep` and every output read each step (`fmi3GetFloat64`,
  `fmi3GetUInt16`, `fmi3GetInt32` of all outputs of those types, one call per type, into
  arrays made once): what the FMU costs an importer that reads every output;
- the same through fmpy's own getters (`slave.getFloat64(vrs)`, `getUInt16`, `getInt32`,
  one call per type each step): what an fmpy user who reads every output pays;
- the low-level FMI 3 API with `fmi3DoStep` alone (the cell's own cost inside the FMU).

The native run is timed as a whole process, and so is the same run of 0 s (the process's
start and the cell's build, about 3 ms): the floor is their difference, as the FMU loops
count neither fmpy's instantiation nor the cell's build. The load average is printed beside
the figures (the machine may be shared). `--repeat N` runs N rounds, each timing every way
once, and keeps each way's fastest: the ways are timed in the same stretches of time, so a
stretch in which the machine (a shared vCPU: whole runs about 1.8x slower at random) is slow
does not fall on one way's repeats alone.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def native(binary: Path, cell: Path, seconds: float) -> float:
    """Wall seconds of `drivetwin run --virtual-seconds`."""
    start = time.perf_counter()
    subprocess.run([str(binary), "run", "--config", str(cell), "--virtual-seconds", str(seconds)],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def simulated(fmu: str, seconds: float, step: float) -> float:
    """Wall seconds of fmpy.simulate_fmu at `step`, every output recorded."""
    import fmpy
    start = time.perf_counter()
    fmpy.simulate_fmu(fmu, stop_time=seconds, step_size=step, output_interval=step,
                      fmi_type="CoSimulation")
    return time.perf_counter() - start


def simulated_loop(unzipped: str, seconds: float, step: float) -> float:
    """Wall seconds of fmpy.simulate_fmu at `step`, every output recorded, on the FMU extracted
    and its description read beforehand, without validation."""
    import fmpy
    md = fmpy.read_model_description(unzipped, validate=False)
    start = time.perf_counter()
    fmpy.simulate_fmu(unzipped, validate=False, model_description=md, stop_time=seconds,
                      step_size=step, output_interval=step, fmi_type="CoSimulation")
    return time.perf_counter() - start


def simulated_minimal(unzipped: str, seconds: float, step: float) -> float:
    """Wall seconds of `simulated_loop` with one output recorded (the first position)."""
    import fmpy
    md = fmpy.read_model_description(unzipped, validate=False)
    first = next(v.name for v in md.modelVariables
                 if v.causality == "output" and v.name.endswith(".position"))
    start = time.perf_counter()
    fmpy.simulate_fmu(unzipped, validate=False, model_description=md, stop_time=seconds,
                      step_size=step, output_interval=step, fmi_type="CoSimulation",
                      output=[first])
    return time.perf_counter() - start


def instantiated(unzipped: str):
    """The extracted FMU instantiated and initialised by fmpy's low-level FMI 3 API."""
    import fmpy
    from fmpy.fmi3 import FMU3Slave
    md = fmpy.read_model_description(unzipped)
    slave = FMU3Slave(guid=md.guid, unzipDirectory=unzipped,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="cell")
    slave.instantiate()
    slave.enterInitializationMode(startTime=0.0)
    slave.exitInitializationMode()
    return md, slave


def do_steps_and_gets(unzipped: str, seconds: float, step: float) -> float:
    """Wall seconds of fmi3DoStep at `step` and every Float64, UInt16 and Int32 output read
    after each step, one call per type into arrays made once (instantiation not counted)."""
    from ctypes import c_double, c_int32, c_uint16, c_uint32
    md, slave = instantiated(unzipped)
    calls = []
    for kind, ctype in (("Float64", c_double), ("UInt16", c_uint16), ("Int32", c_int32)):
        vrs = [v.valueReference for v in md.modelVariables
               if v.causality == "output" and v.type == kind]
        if vrs:
            calls.append((getattr(slave, "fmi3Get" + kind), (c_uint32 * len(vrs))(*vrs),
                          len(vrs), (ctype * len(vrs))()))
    n = round(seconds / step)
    component = slave.component
    start = time.perf_counter()
    for i in range(n):
        slave.doStep(currentCommunicationPoint=i * step, communicationStepSize=step)
        for get, vrs, count, values in calls:
            get(component, vrs, count, values, count)
    wall = time.perf_counter() - start
    slave.terminate()
    slave.freeInstance()
    return wall


def do_steps_and_fmpy_gets(unzipped: str, seconds: float, step: float) -> float:
    """Wall seconds of fmi3DoStep at `step` and every Float64, UInt16 and Int32 output read
    after each step through fmpy's getters (`slave.getFloat64(vrs)`: one call per type, the
    value references as a list, the values back as one), instantiation not counted."""
    md, slave = instantiated(unzipped)
    calls = []
    for kind in ("Float64", "UInt16", "Int32"):
        vrs = [v.valueReference for v in md.modelVariables
               if v.causality == "output" and v.type == kind]
        if vrs:
            calls.append((getattr(slave, "get" + kind), vrs))
    n = round(seconds / step)
    start = time.perf_counter()
    for i in range(n):
        slave.doStep(currentCommunicationPoint=i * step, communicationStepSize=step)
        for get, vrs in calls:
            get(vrs)
    wall = time.perf_counter() - start
    slave.terminate()
    slave.freeInstance()
    return wall


def do_steps(unzipped: str, seconds: float, step: float) -> float:
    """Wall seconds of fmi3DoStep alone at `step` (instantiation not counted)."""
    _, slave = instantiated(unzipped)
    n = round(seconds / step)
    start = time.perf_counter()
    for i in range(n):
        slave.doStep(currentCommunicationPoint=i * step, communicationStepSize=step)
    wall = time.perf_counter() - start
    slave.terminate()
    slave.freeInstance()
    return wall


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cell", type=Path, default=ROOT / "examples/cell_fmu/ten_drives.toml")
    p.add_argument("--seconds", type=float, default=10.0, help="virtual seconds of each run")
    p.add_argument("--step", type=float, default=1e-3, help="the importer's step, s")
    p.add_argument("--repeat", type=int, default=1,
                   help="rounds of every way; each way's fastest is kept")
    p.add_argument("--binary", type=Path, default=Path(os.environ.get(
        "DRIVETWIN_BIN", ROOT / "target/release/drivetwin")))
    a = p.parse_args()
    import fmpy  # imported before any run is timed: its import is not the FMU's
    with tempfile.TemporaryDirectory() as tmp:
        fmu = str(Path(tmp) / "cell.fmu")
        subprocess.run([str(a.binary), "fmu", "--config", str(a.cell), "--output", fmu],
                       check=True, stdout=subprocess.DEVNULL)
        # One extraction for the ways that step the FMU extracted (`simulate_fmu` as called
        # extracts it itself, and removes it).
        unzipped = fmpy.extract(fmu, unzipdir=str(Path(tmp) / "cell"))
        load = os.getloadavg()[0]
        ways = {
            "start": lambda: native(a.binary, a.cell, 0.0),
            "native": lambda: native(a.binary, a.cell, a.seconds),
            "sim": lambda: simulated(fmu, a.seconds, a.step),
            "loop": lambda: simulated_loop(unzipped, a.seconds, a.step),
            "min": lambda: simulated_minimal(unzipped, a.seconds, a.step),
            "gets": lambda: do_steps_and_gets(unzipped, a.seconds, a.step),
            "fmpy_gets": lambda: do_steps_and_fmpy_gets(unzipped, a.seconds, a.step),
            "steps": lambda: do_steps(unzipped, a.seconds, a.step),
        }
        best = {k: float("inf") for k in ways}
        for _ in range(max(a.repeat, 1)):
            for k, way in ways.items():
                best[k] = min(best[k], way())
    t_start, t_whole = best["start"], best["native"]
    # The floor without the process's start (a short run's start can outweigh its run: then
    # the whole process).
    t_native = t_whole - t_start if t_whole > 2 * t_start else t_whole
    t_sim, t_loop, t_min = best["sim"], best["loop"], best["min"]
    t_gets, t_fmpy_gets, t_steps = best["gets"], best["fmpy_gets"], best["steps"]
    v = a.seconds
    print(f"cell {a.cell.name}, {v:g} s of virtual time, step {a.step * 1e3:g} ms, "
          f"load average {load:.2f} ({os.cpu_count()} CPUs)")
    print(f"native  (the process of 0 s: its start and the cell's build): {t_start:8.3f} s wall")
    print(f"native  (drivetwin run --virtual-seconds, minus its start): {t_native:8.3f} s wall, "
          f"{v / t_native:8.1f}x real time")
    print(f"FMU     (fmpy.simulate_fmu, outputs kept): {t_sim:8.3f} s wall, {v / t_sim:8.1f}x real time, "
          f"{100 * t_native / t_sim:5.1f} % of native")
    print(f"FMU     (simulate_fmu, stepping loop only): {t_loop:8.3f} s wall, {v / t_loop:8.1f}x real time, "
          f"{100 * t_native / t_loop:5.1f} % of native")
    print(f"FMU     (simulate_fmu loop, one output):    {t_min:8.3f} s wall, {v / t_min:8.1f}x real time, "
          f"{100 * t_native / t_min:5.1f} % of native")
    print(f"FMU     (doStep + every output, low-level): {t_gets:8.3f} s wall, {v / t_gets:8.1f}x real time, "
          f"{100 * t_native / t_gets:5.1f} % of native")
    print(f"FMU     (doStep + every output, fmpy's getters): {t_fmpy_gets:8.3f} s wall, "
          f"{v / t_fmpy_gets:8.1f}x real time, {100 * t_native / t_fmpy_gets:5.1f} % of native")
    print(f"FMU     (fmi3DoStep alone, low-level API): {t_steps:8.3f} s wall, {v / t_steps:8.1f}x real time, "
          f"{100 * t_native / t_steps:5.1f} % of native")
    return 0


if __name__ == "__main__":
    sys.exit(main())
