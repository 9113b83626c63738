"""S003b heading consistency budget: which error source makes the seed-003 estimator's
heading NEES leave its band after the commanded switch.

Runs the S003b case's ``with_conversion`` variant on seeds 1..N six times, changing only
the IMU: the seed's (``models/imu/seed003_vehicle.toml``: constant biases 0.015 deg/h and
85 ug, fixed, the same on every axis and every seed; noise 0.0007 deg/sqrt(h) and
10 ug/sqrt(Hz)), its constant biases alone, its noise alone, its gyro noise alone, its
accelerometer noise alone, and an ideal one (every error 10^-4 of the seed's or less).
The BDS and Doppler draws are the same in all (same seeds); the estimator's
configuration stays the seed's IMU in all of them. Prints, per IMU:

* the fraction of epochs whose heading NEES lies in its 95 % band (1 dof), pooled over
  the seeds, before the switch (after 60 s) and from the switch + 60 s on -- the figures of
  ``benchmarks/s003_monte_carlo.py`` section 4;
* the heading error at the end of the drive per seed, the filter's sigma there, and the
  RMS over the seeds;
* for the non-ideal IMUs, the heading error minus the ideal IMU's on the same seed
  (what that IMU error did, as the errors add): mean and spread over the seeds.

    .venv/bin/python benchmarks/s003_heading_budget.py [--runs 10] [--at 590]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from imu_budget import launch  # noqa: E402
from s003_monte_carlo import _one  # noqa: E402

from bench.scoring.align import nav_errors  # noqa: E402
from bench.scoring.consistency import nees_series  # noqa: E402
from bench.scoring.data import load_run  # noqa: E402

CASE = ROOT / "test_cases" / "S003b_frame_switch_commanded.toml"
SCRIPT = "scenarios/S003b_commanded_switch.toml"
_G0, _A0 = "0.000001 deg/h", "0.00001 ug"
_NG0, _NA0 = "0.000001 deg/sqrt(h)", "0.00001 ug/sqrt(Hz)"
#: label -> (gyro table, accel table); None: the seed's own grade file
GRADES = {
    "seed's IMU": None,
    "biases only": (f'bias = "0.015 deg/h"\nnoise = "{_NG0}"', f'bias = "85 ug"\nnoise = "{_NA0}"'),
    "noise only": (f'bias = "{_G0}"\nnoise = "0.0007 deg/sqrt(h)"', f'bias = "{_A0}"\nnoise = "10 ug/sqrt(Hz)"'),
    "gyro noise": (f'bias = "{_G0}"\nnoise = "0.0007 deg/sqrt(h)"', f'bias = "{_A0}"\nnoise = "{_NA0}"'),
    "accel noise": (f'bias = "{_G0}"\nnoise = "{_NG0}"', f'bias = "{_A0}"\nnoise = "10 ug/sqrt(Hz)"'),
    "ideal IMU": (f'bias = "{_G0}"\nnoise = "{_NG0}"', f'bias = "{_A0}"\nnoise = "{_NA0}"'),
}
ARCMIN = math.radians(1.0 / 60.0)


def _case_for(grade: Path | None, tmp: Path, tag: str) -> Path:
    text = CASE.read_text().replace(f'script = "{SCRIPT}"', f'script = "{(CASE.parent / SCRIPT).as_posix()}"')
    if grade is not None:
        text = text.replace('grade = "seed003_vehicle"', f'grade = "{grade.as_posix()}"')
    out = tmp / f"S003b_{tag}.toml"
    out.write_text(text)
    return out


def _end(path: Path, at_s: float) -> tuple[float, float]:
    """Heading error and the filter's heading sigma (arcmin) at ``at_s``."""
    d = load_run(path)
    e = nav_errors(d.truth, d.nav)
    q = d.quality[np.argsort(d.quality["t_ns"], kind="stable")]
    _, nees = nees_series(e, q, "heading")
    i = min(int(np.searchsorted(e.t_ns * 1e-9, at_s)), len(e.t_ns) - 1)
    err = float(e.att[i, 0])
    return err / ARCMIN, abs(err) / max(math.sqrt(float(nees[i])), 1e-12) / ARCMIN


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--at", type=float, default=590.0, help="time of the end-of-drive figures, s")
    args = ap.parse_args()
    seeds = list(range(1, args.runs + 1))
    print(f"S003b with_conversion, seeds 1-{args.runs}: heading consistency by IMU")
    results: dict[str, list[tuple[float, float]]] = {}
    with tempfile.TemporaryDirectory() as tmpd:
        tmp = Path(tmpd)
        seed_args = [a for s in seeds for a in ("--seed", str(s))]
        procs = launch(GRADES, lambda g, tag: _case_for(g, tmp, tag), tmp, ["--variant", "with_conversion", *seed_args])
        print(f"  {'IMU':<12} {'NEES in band before':>20} {'after switch+60 s':>18} "
              f"{'error at ' + format(args.at, '.0f') + ' s, RMS':>22} {'sigma there':>12}")
        for label, k, p in procs:
            _, err = p.communicate()
            rec = tmp / f"out{k}" / "recordings" / "S003b"
            paths = [rec / f"S003b-with_conversion-s{s}.mcap" for s in seeds]
            if not all(x.exists() for x in paths):
                sys.stderr.write(err)
                raise SystemExit(f"{label}: a run left no recording (exit {p.returncode})")
            one = [_one(x, 60.0) for x in paths]
            ends = [_end(x, args.at) for x in paths]
            results[label] = ends
            rms = math.sqrt(np.mean([e * e for e, _ in ends]))
            sig = float(np.median([s for _, s in ends]))
            pre = 100 * np.mean([o["nees_heading_pre"] for o in one])
            post = 100 * np.mean([o["nees_heading_post"] for o in one])
            print(f"  {label:<12} {pre:19.1f}% {post:17.1f}% {rms:21.2f}' {sig:11.2f}'")
    print(f"\n  heading error at {args.at:.0f} s per seed (arcmin):")
    for label, ends in results.items():
        print(f"  {label:<12} " + " ".join(f"{e:+6.2f}" for e, _ in ends))
    ideal = np.array([e for e, _ in results["ideal IMU"]])
    print("\n  the IMU error's part (minus the ideal IMU's error on the same seed):")
    for label in [g for g in GRADES if g != "ideal IMU"]:
        d = np.array([e for e, _ in results[label]]) - ideal
        neg = int(np.sum(d < 0))
        print(f"  {label:<12} mean {d.mean():+6.2f}'  spread (sd) {d.std(ddof=1):5.2f}'  "
              f"negative on {neg} of {len(d)} seeds")
    return 0


if __name__ == "__main__":
    sys.exit(main())
