"""Runs a drivetwin cell as an FMU with fmpy, driving a torque profile on its drive's shaft,
and prints (and, with matplotlib, plots) the shaft's position (docs/cosimulation.md).

    scripts/cell-fmu                      # target/fmu/cell.fmu: examples/cell_fmu/cell.toml
    python3 examples/cell_fmu.py target/fmu/cell.fmu [--plot cell_fmu.png]

The FMU's start (examples/cell_fmu/start.toml) enables the CMMP-AS in profile velocity mode;
the load torque below pushes against it in steps, and the speed controller answers with
current.
"""

from __future__ import annotations

import argparse

import fmpy
import numpy as np


def torque_profile(stop: float) -> np.ndarray:
    """0 N·m, then 0.3, 0.6 and -0.3 N·m steps: (time, torque) rows fmpy interpolates."""
    points = [(0.0, 0.0), (1.0, 0.0), (1.0, 0.3), (2.0, 0.3), (2.0, 0.6), (3.0, 0.6),
              (3.0, -0.3), (stop, -0.3)]
    return np.array(points, dtype=[("time", np.float64), ("node1.load_torque", np.float64)])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("fmu", help="the cell FMU (drivetwin fmu --output …)")
    parser.add_argument("--stop", type=float, default=4.0, help="stop time, s")
    parser.add_argument("--step", type=float, default=1e-3, help="communication step, s")
    parser.add_argument("--plot", help="write a plot of position and current to this PNG")
    args = parser.parse_args()

    r = fmpy.simulate_fmu(
        args.fmu, stop_time=args.stop, step_size=args.step, output_interval=args.step,
        input=torque_profile(args.stop),
        output=["node1.load_torque", "node1.position", "node1.velocity", "node1.current",
                "node1.statusword"],
    )
    print(f"{'t / s':>7} {'load / N·m':>11} {'position / rad':>15} {'velocity / rad/s':>17} "
          f"{'current / A':>12} statusword")
    every = max(1, round(0.25 / args.step))
    for row in r[::every]:
        print(f"{row['time']:7.3f} {row['node1.load_torque']:11.3f} {row['node1.position']:15.6f} "
              f"{row['node1.velocity']:17.6f} {row['node1.current']:12.6f} "
              f"{int(row['node1.statusword']):#06x}")
    if args.plot:
        try:
            import matplotlib
        except ImportError:
            print("--plot needs matplotlib (pip install matplotlib)")
            return
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(8, 5))
        ax1.plot(r["time"], r["node1.position"])
        ax1.set_ylabel("position / rad")
        ax2.plot(r["time"], r["node1.current"], label="current / A")
        ax2.plot(r["time"], r["node1.load_torque"], label="load torque / N·m")
        ax2.set_xlabel("t / s")
        ax2.legend()
        fig.savefig(args.plot, dpi=100)
        print(f"plot: {args.plot}")


if __name__ == "__main__":
    main()
