"""AURT's input for the UR10e harmonic run: the recorded AURT run of benchmarks/recorded/aurt_ur10e.json.

Run by hand only (not in CI, not by any test); it writes outside the repository:

    python benchmarks/recorded/aurt_input.py RUN.csv OUT_DIR [--rate 0]

RUN.csv is Mamedov et al.'s headerless 31-column log (``../shared/realdata/ur10e_mamedov2020/
identification_data/ur-20_02_19_15harm50sec.csv``: t, q1..q6, qd1..qd6, i1..i6, i_des1..6, tau_des1..6;
SOURCE.md there). OUT_DIR gets

- ``ur10e_mdh.csv``: the table AURT's ``compile-rbd --mdh`` reads (columns d, a, alpha; one row per joint).
  AURT builds link i from d of row i and a, alpha of row i-1 (``RigidBodyDynamics._position_vectors``), so
  the UR10e's standard DH rows (recipes/robots/ur10e.yaml, issue 24) written as they are are the modified
  DH chain of the same arm (a standard chain regrouped; the last row's a = alpha = 0 leave no tool frame).
  AURT's own ``resources/robot_parameters/ur5e_dh.csv`` is written the same way.
- ``ur10e_harmonic.csv`` (``--rate 0``: as logged) or ``ur10e_harmonic_<rate>hz.csv``: the log in the
  format AURT's ``RobotData`` reads (space-separated, a header, joints numbered from 0: ``timestamp``,
  ``actual_q_k``, ``actual_qd_k``, ``actual_current_k``, ``target_current_k``, ``target_moment_k``, and
  ``target_q_k``, ``target_qd_k``, ``target_qdd_k``, which the log does not record and AURT's calibration
  does not read (only its plots do): written as the actual position and velocity and a zero acceleration).
  AURT fits the motor current itself (no drive gains).

``--rate R`` (R > 0) resamples every column linearly onto a uniform grid of R Hz over the logged time span;
the default (0) writes the log at its own samples, the input of the recorded run. AURT's trajectory filter
has a fixed 50 Hz cut-off (``RobotCalibration.f_dyn`` = 10 Hz, times 5): the Nyquist frequency of a 100 Hz
log. On this log AURT's most frequent time step (``RobotData.dt_nominal``) reads 0.00999999999999 s, so the
filter's normalised cut-off is 0.99999999999909 and scipy designs it (checked with AURT's own reader and
filter); a log whose most frequent step read a hair over 10 ms would be refused ("Digital filter critical
frequencies must be 0 < Wn < fs/2"), which resampling to 500 Hz (the rate of UR's RTDE interface that AURT
was written for) avoids without adding content (linear interpolation adds nothing above the log's own
Nyquist frequency).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

#: the UR10e's standard DH parameters (recipes/robots/ur10e.yaml): d, a, alpha per joint
UR10E_DH = [("0.1807", "0", "pi/2"), ("0", "-0.6127", "0"), ("0", "-0.57155", "0"),
            ("0.17415", "0", "pi/2"), ("0.11985", "0", "-pi/2"), ("0.11655", "0", "0")]
N = 6


def columns(raw: np.ndarray) -> dict[str, np.ndarray]:
    """AURT's columns from the 31-column log (time from zero)."""
    out = {"timestamp": raw[:, 0] - raw[0, 0]}
    for k in range(N):
        q, qd = raw[:, 1 + k], raw[:, 7 + k]
        out.update({f"target_q_{k}": q, f"target_qd_{k}": qd, f"target_qdd_{k}": np.zeros(len(raw)),
                    f"target_current_{k}": raw[:, 19 + k], f"actual_current_{k}": raw[:, 13 + k],
                    f"target_moment_{k}": raw[:, 25 + k], f"actual_q_{k}": q, f"actual_qd_{k}": qd})
    return out


def resample(cols: dict[str, np.ndarray], rate: float) -> dict[str, np.ndarray]:
    """Every column linearly interpolated onto a uniform grid of ``rate`` Hz over the logged span."""
    t = cols["timestamp"]
    grid = np.arange(0.0, t[-1] + 0.5 / rate, 1.0 / rate)
    grid = grid[grid <= t[-1]]
    return {k: (grid if k == "timestamp" else np.interp(grid, t, v)) for k, v in cols.items()}


def write(path: Path, cols: dict[str, np.ndarray]) -> None:
    names = list(cols)
    data = np.column_stack([cols[k] for k in names])
    np.savetxt(path, data, fmt="%.6f", delimiter=" ", header=" ".join(names), comments="")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run")
    ap.add_argument("out_dir")
    ap.add_argument("--rate", type=float, default=0.0, help="resample to this rate [Hz]; 0: as logged")
    args = ap.parse_args(argv)
    out = Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "ur10e_mdh.csv").write_text("d,a,alpha\n" + "".join(",".join(r) + "\n" for r in UR10E_DH))
    cols = columns(np.loadtxt(args.run, delimiter=","))
    name = "ur10e_harmonic.csv"
    if args.rate > 0:
        cols = resample(cols, args.rate)
        name = f"ur10e_harmonic_{args.rate:g}hz.csv"
    write(out / name, cols)
    print(f"{out / name}: {len(cols['timestamp'])} rows, {cols['timestamp'][-1]:.3f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
