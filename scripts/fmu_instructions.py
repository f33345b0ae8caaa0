#!/usr/bin/env python3
"""Instructions of a cell stepped as an FMU by fmpy at 1 ms against the same cell's own run on
the virtual clock, counted by callgrind (docs/performance.md, "The cell as an FMU"): a count
the machine's load does not move, where `scripts/fmu_speed.py` times wall clocks.

    scripts/cell-fmu && python3 scripts/fmu_instructions.py            # 1000 steps, ten drives
    python3 scripts/fmu_instructions.py --steps 200 --cell examples/cell_fmu/ten_drives.toml

Each figure is a difference of two whole runs under `valgrind --tool=callgrind`, so that the
start of the process, fmpy's import and the cell's building drop out:

- native: `drivetwin run --config CELL --virtual-seconds S` minus the same with 0 s;
- `doStep` alone: fmpy's low-level FMI 3 API (`fmpy.fmi3.FMU3Slave`) stepping the FMU
  `--steps` times at `--step`, minus the same with 0 steps;
- `doStep` + every output: the same, each step followed by `fmi3GetFloat64`, `fmi3GetUInt16`
  and `fmi3GetInt32` of every output of those types (one call per type, into arrays made
  once), as `scripts/fmu_speed.py` reads them;
- `doStep` + every output through fmpy's getters: the same reads as `slave.getFloat64(vrs)`,
  `getUInt16`, `getInt32` (fmpy's wrappers: the value references as a list, the values back
  as one), as an fmpy user who reads every output writes them;
- `simulate_fmu`: `fmpy.simulate_fmu` on the extracted FMU, its description read beforehand
  and not validated, every output recorded at every step (fmpy's stepping loop and recorder),
  minus the same with a stop time of 0.

Each run is counted with Python's hashing seeded and the address space not randomised
(`setarch -R`), so that the same binary gives the same count to a few thousand instructions.

Beside each FMU loop the instructions inside libffi's `ffi_call` (inclusive, from
`callgrind_annotate --inclusive=yes`), through which ctypes makes every call into the FMU:
the FMU's own work (`fmi3DoStep` and the gets); the rest of the loop is ctypes and Python. The FMU is packed from the cell by `--binary` (`drivetwin fmu`, which
takes the library beside it).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: The function through which ctypes calls the FMU: its inclusive instructions are the FMU's.
FMU_FUNCTIONS = ("ffi_call",)


def loop(unzipped: str, kind: str, steps: int, step: float) -> None:
    """`steps` doSteps of `step` on the extracted FMU, with every output read after each when
    `kind` is "gets", through `fmpy.simulate_fmu` when it is "simulate" (run inside
    callgrind)."""
    from ctypes import c_double, c_int32, c_uint16, c_uint32

    import fmpy
    from fmpy.fmi3 import FMU3Slave

    md = fmpy.read_model_description(unzipped, validate=False)
    if kind == "simulate":
        fmpy.simulate_fmu(unzipped, validate=False, model_description=md,
                          stop_time=steps * step, step_size=step, output_interval=step,
                          fmi_type="CoSimulation")
        return
    slave = FMU3Slave(guid=md.guid, unzipDirectory=unzipped,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="cell")
    slave.instantiate()
    slave.enterInitializationMode(startTime=0.0)
    slave.exitInitializationMode()
    calls = []
    if kind == "fmpy_gets":
        for name in ("Float64", "UInt16", "Int32"):
            vrs = [v.valueReference for v in md.modelVariables
                   if v.causality == "output" and v.type == name]
            if vrs:
                calls.append((getattr(slave, "get" + name), vrs))
        for i in range(steps):
            slave.doStep(currentCommunicationPoint=i * step, communicationStepSize=step)
            for get, vrs in calls:
                get(vrs)
        slave.terminate()
        slave.freeInstance()
        return
    if kind == "gets":
        for name, ctype in (("Float64", c_double), ("UInt16", c_uint16), ("Int32", c_int32)):
            vrs = [v.valueReference for v in md.modelVariables
                   if v.causality == "output" and v.type == name]
            if vrs:
                calls.append((getattr(slave, "fmi3Get" + name), (c_uint32 * len(vrs))(*vrs),
                              len(vrs), (ctype * len(vrs))()))
    component = slave.component
    for i in range(steps):
        slave.doStep(currentCommunicationPoint=i * step, communicationStepSize=step)
        for get, vrs, count, values in calls:
            get(component, vrs, count, values, count)
    slave.terminate()
    slave.freeInstance()


def callgrind(command: list[str], out: Path) -> tuple[int, dict[str, int]]:
    """The instructions of `command` under callgrind, and the inclusive instructions of each
    of [`FMU_FUNCTIONS`] it called."""
    # One hash seed and no address randomisation: Python's randomised hashing and its
    # objects' addresses (hashes of identity, the order of sets) move its own count from run
    # to run (by up to 10 M instructions in a run of 1000 steps; `setarch -R`: by 20 k).
    fixed = ["setarch", "-R"] if shutil.which("setarch") else []
    subprocess.run([*fixed, "valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
                    *command],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                   env={**os.environ, "PYTHONHASHSEED": "0"})
    text = out.read_text(errors="replace")
    total = re.search(r"^(?:summary|totals):\s+(\d+)", text, re.M)
    if total is None:
        raise SystemExit(f"{out}: no instruction total")
    annotated = subprocess.run(
        ["callgrind_annotate", "--inclusive=yes", "--threshold=100", str(out)],
        check=True, capture_output=True, text=True).stdout
    inside = {}
    for name in FMU_FUNCTIONS:
        m = re.search(r"^\s*([\d,]+)\s+\([^)]*\)\s+\S*:" + name + r"\b", annotated, re.M)
        inside[name] = int(m.group(1).replace(",", "")) if m else 0
    return int(total.group(1)), inside


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cell", type=Path, default=ROOT / "examples/cell_fmu/ten_drives.toml")
    p.add_argument("--steps", type=int, default=1000, help="steps of each FMU loop")
    p.add_argument("--step", type=float, default=1e-3, help="the importer's step, s")
    p.add_argument("--binary", type=Path, default=Path(os.environ.get(
        "DRIVETWIN_BIN", ROOT / "target/release/drivetwin")))
    p.add_argument("--kinds", default="steps,gets,fmpy_gets,simulate",
                   help="the FMU loops to count: steps, gets, fmpy_gets, simulate "
                        "(comma-separated)")
    p.add_argument("--loop", nargs=3, metavar=("UNZIPPED", "KIND", "STEPS"),
                   help=argparse.SUPPRESS)
    a = p.parse_args()
    if a.loop:
        unzipped, kind, steps = a.loop
        loop(unzipped, kind, int(steps), a.step)
        return 0
    import fmpy
    seconds = a.steps * a.step
    with tempfile.TemporaryDirectory() as tmp:
        fmu = str(Path(tmp) / "cell.fmu")
        subprocess.run([str(a.binary), "fmu", "--config", str(a.cell), "--output", fmu],
                       check=True, stdout=subprocess.DEVNULL)
        unzipped = fmpy.extract(fmu, unzipdir=str(Path(tmp) / "cell"))
        load = os.getloadavg()[0]
        out = Path(tmp) / "callgrind.out"
        run = [str(a.binary), "run", "--config", str(a.cell), "--virtual-seconds"]
        native = callgrind(run + [f"{seconds:g}"], out)[0] - callgrind(run + ["0"], out)[0]
        rows = []
        for kind, label in (("steps", "doStep alone"), ("gets", "doStep + every output"),
                            ("fmpy_gets", "doStep + every output, fmpy's getters"),
                            ("simulate", "simulate_fmu, every output recorded")):
            if kind not in a.kinds.split(","):
                continue
            me = [sys.executable, __file__, "--step", str(a.step), "--loop", unzipped, kind]
            full, inside = callgrind(me + [str(a.steps)], out)
            empty, inside0 = callgrind(me + ["0"], out)
            fmu = sum(inside.values()) - sum(inside0.values())
            rows.append((label, full - empty, fmu))
    print(f"cell {a.cell.name}, {a.steps} steps of {a.step * 1e3:g} ms, callgrind instructions, "
          f"load average {load:.2f} (instructions do not depend on it)")
    print(f"native  (drivetwin run --virtual-seconds {seconds:g} minus 0): {native / 1e6:8.1f} M")
    for label, loop_ir, fmu in rows:
        print(f"FMU     ({label}): loop {loop_ir / 1e6:8.1f} M, {100 * native / loop_ir:5.1f} % "
              f"of native; inside the FMU (ffi_call) {fmu / 1e6:.1f} M")
    return 0


if __name__ == "__main__":
    sys.exit(main())
