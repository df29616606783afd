"""Write the small example logs in sample_logs/ (CSV and Parquet, truth labels included).

    python scripts/make_sample_logs.py [--out sample_logs]

Each log is a shipped recipe on a shipped plant, shortened with ``duration_scale`` so the folder stays
a few MB; sample_logs/README.md describes them. Deterministic: the same code gives the same files.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from frictid.io.logs import write_logs
from frictid.plant import load_recipe, simulate_recipe

ROOT = Path(__file__).resolve().parents[1]

# name, recipe, plant, duration_scale, joints, recipe overrides
SAMPLES = [
    ("hydraulic_sweep.csv", "constant_velocity_sweep", "hydraulic", 0.5, None,
     {"experiments": [{"kind": "constant_velocity", "velocities": {"min": 0.01, "max": 0.95, "count": 8},
                       "plateau": 3.0, "min_plateau": 0.5, "gap": 0.3, "rest": 1.0}]}),
    ("direct_drive_presliding.parquet", "ramp_presliding", "direct_drive", 0.25, ["j1"], None),
    ("hydraulic_steps.csv", "torque_steps", "hydraulic", 1.0, None, None),
    ("geared_duty_cycle.parquet", "duty_cycle", "geared_industrial", 0.01, None,
     {"experiments": [
         {"kind": "duty_cycle", "duty": 0.25, "cycles": 3, "cycle_time": 240.0, "cold_start": True, "rest": 2.0},
         {"kind": "duty_cycle", "duty": 1.0, "cycles": 3, "cycle_time": 240.0, "cold_start": True, "rest": 2.0},
     ]}),
    ("linear_slide_multisine.csv", "multisine", "linear_slide", 0.12, None, None),
    ("direct_drive_sweep.parquet", "constant_velocity_sweep", "direct_drive", 0.2, ["j1"], None),
]


def make(out: Path, seed: int = 0) -> list[tuple[str, int]]:
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for name, recipe, plant, scale, joints, over in SAMPLES:
        rec, _ = load_recipe(recipe)
        if over:
            rec = type(rec).model_validate({**rec.model_dump(), **over})
        logs = simulate_recipe(rec, plant=plant, seed=seed, duration_scale=scale, joints=joints)
        path = out / name
        write_logs(logs, str(path))
        written.append((name, sum(lg.n for lg in logs)))
    return written


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "sample_logs"))
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    for name, rows in make(Path(a.out), a.seed):
        size = (Path(a.out) / name).stat().st_size
        print(f"{name:36s} {rows:8d} rows {size / 1e6:6.2f} MB")


if __name__ == "__main__":
    main()
