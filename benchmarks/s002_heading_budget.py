"""S002 heading error budget: which IMU error the seed-002 estimator's heading error comes from.

Runs the S002 case's ``with_detection`` variant on one seed four times, changing only the
IMU: the seed's (``models/imu/seed002.toml``: constant biases 0.02 deg/h and 98 ug, noise
0.02 deg/sqrt(h) and 49 ug/sqrt(Hz)), its constant biases alone, its noise alone, and an
ideal one (every error 10^-4 of the seed's or less). The estimator's configuration stays
the seed's IMU in all four. Prints, per IMU: the heading error and the filter's heading
sigma at the end of the alignment (181 s) and at the end of the drive, the largest heading
error over sigma while driving, and the fraction of the fault-free epochs whose position
NEES lies in its 95 % band (the case's NEES-POS).

    .venv/bin/python benchmarks/s002_heading_budget.py [--seed 4]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from imu_budget import launch  # noqa: E402

from bench.scoring.align import nav_errors  # noqa: E402
from bench.scoring.consistency import chi2_bounds, nees_series  # noqa: E402
from bench.scoring.data import load_run  # noqa: E402

CASE = ROOT / "test_cases" / "S002_sins_odometer_faults.toml"
_G0, _A0 = "0.000001 deg/h", "0.00001 ug"  # "none": far below anything the drive can show
_NG0, _NA0 = "0.000001 deg/sqrt(h)", "0.00001 ug/sqrt(Hz)"
#: label -> (gyro table, accel table); None: the seed's own grade file
GRADES = {
    "seed's IMU": None,
    "biases only": (f'bias = "0.02 deg/h"\nnoise = "{_NG0}"', f'bias = "98 ug"\nnoise = "{_NA0}"'),
    "noise only": (f'bias = "{_G0}"\nnoise = "0.02 deg/sqrt(h)"', f'bias = "{_A0}"\nnoise = "49 ug/sqrt(Hz)"'),
    "ideal IMU": (f'bias = "{_G0}"\nnoise = "{_NG0}"', f'bias = "{_A0}"\nnoise = "{_NA0}"'),
}
ALIGNED_S = 181.0


def _case_for(grade: Path | None, tmp: Path, tag: str) -> Path:
    """A copy of the case with absolute paths and, if given, the IMU grade file ``grade``."""
    text = CASE.read_text()
    doc = tomllib.loads(text)
    base = CASE.parent
    for rel in doc.get("fault_files", []):
        text = text.replace(f'"{rel}"', f'"{(base / rel).as_posix()}"')
    script = doc["scenario"]["script"]
    text = text.replace(f'script = "{script}"', f'script = "{(base / script).as_posix()}"')
    if grade is not None:
        text = text.replace('grade = "seed002"', f'grade = "{grade.as_posix()}"')
    out = tmp / f"S002_{tag}.toml"
    out.write_text(text)
    return out


def _figures(path: Path) -> dict[str, float]:
    d = load_run(path)
    q = d.quality[np.argsort(d.quality["t_ns"], kind="stable")]
    e = nav_errors(d.truth, d.nav)
    te = e.t_ns * 1e-9
    has_h, nees_h = nees_series(e, q, "heading")
    has_p, nees_p = nees_series(e, q, "position")
    drive = e.usable & has_h & (te >= ALIGNED_S)
    free = e.usable & has_p & (te >= 180.0)
    for w in d.faults:
        free &= ~((te >= w.start_ns * 1e-9) & (te < w.end_ns * 1e-9 + 30.0))
    lo, hi = chi2_bounds(3, 0.95)
    i0 = int(np.flatnonzero(drive)[0])
    i1 = int(np.flatnonzero(drive)[-1])
    sig = np.abs(e.att[:, 0]) / np.maximum(np.sqrt(nees_h), 1e-12)  # the filter's heading sigma, rad
    arcmin = 180.0 / np.pi * 60.0
    return {
        "err0": e.att[i0, 0] * arcmin, "sig0": sig[i0] * arcmin,
        "err1": e.att[i1, 0] * arcmin, "sig1": sig[i1] * arcmin,
        "zmax": float(np.sqrt(np.max(nees_h[drive]))),
        "nees": float(np.mean((nees_p[free] >= lo) & (nees_p[free] <= hi))),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=4)
    args = ap.parse_args()
    print(f"S002 with_detection, seed {args.seed}: heading error (arcmin) and the filter's sigma, by IMU")
    with tempfile.TemporaryDirectory() as tmpd:
        tmp = Path(tmpd)
        procs = launch(GRADES, lambda g, tag: _case_for(g, tmp, tag), tmp,
                       ["--seed", str(args.seed), "--variant", "with_detection"])
        print(f"  {'IMU':<12} {'after alignment':>22} {'end of the drive':>22} {'max |error|/sigma':>18} "
              f"{'position NEES in band':>22}")
        for label, k, p in procs:
            _, err = p.communicate()
            rec = tmp / f"out{k}" / "recordings" / "S002" / f"S002-with_detection-s{args.seed}.mcap"
            if not rec.exists():
                sys.stderr.write(err)
                raise SystemExit(f"{label}: the run left no recording (exit {p.returncode})")
            f = _figures(rec)
            print(f"  {label:<12} {f['err0']:+8.1f}' (sigma {f['sig0']:4.1f}') {f['err1']:+8.1f}' "
                  f"(sigma {f['sig1']:4.1f}') {f['zmax']:18.2f} {100 * f['nees']:21.1f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
