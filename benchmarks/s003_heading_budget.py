"""S003b heading consistency budget: the seed-003 estimator's heading NEES after the
commanded switch, by IMU error source and over as many seeds as asked.

Runs the S003b case's ``with_conversion`` variant on seeds 1..N once per IMU grade,
changing only the IMU (``--grades``, default all but ``gyro`` and ``accel``):

* ``seed``: the seed's (``models/imu/seed003_vehicle.toml``: constant biases 0.015 deg/h
  and 85 ug, fixed: the same on every axis and every seed; noise 0.0007 deg/sqrt(h) and
  10 ug/sqrt(Hz));
* ``drawn``: the same with the biases drawn per run (``bias_draw = "random"``, 1-sigma
  0.015 deg/h and 85 ug): the population the filter's bias prior describes;
* ``biases``, ``noise``, ``gyro``, ``accel``: the seed's constant biases, noise, gyro noise,
  accelerometer noise alone;
* ``ideal``: every error 10^-4 of the seed's or less.

The BDS and Doppler draws are the same for every grade (same seeds); the estimator's
configuration stays the seed's IMU. Prints per grade: the fraction of epochs whose heading
NEES lies in its 95 % band (1 dof), pooled over the seeds, before the switch (after 60 s)
and from the switch + 60 s on (``benchmarks/s003_monte_carlo.py`` section 4); the heading
error at ``--at`` s, mean and RMS over the seeds, and the filter's sigma there; and the
mean rounding of the angle increments on the wire (ICD frame minus the IMU's value, as a
rate per axis): an IMU whose noise is below the 1e-9 rad LSB is not dithered, and the
rounding of each frame adds up to a drift.

    .venv/bin/python benchmarks/s003_heading_budget.py [--runs 10] [--grades seed,drawn,...] [--at 590]
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

from bench.record.reader import RecordingReader  # noqa: E402
from bench.wire import imu as imu_codec  # noqa: E402

CASE = ROOT / "test_cases" / "S003b_frame_switch_commanded.toml"
SCRIPT = "scenarios/S003b_commanded_switch.toml"
_G0, _A0 = "0.000001 deg/h", "0.00001 ug"
_NG0, _NA0 = "0.000001 deg/sqrt(h)", "0.00001 ug/sqrt(Hz)"
_BIAS = 'bias = "0.015 deg/h"', 'bias = "85 ug"'
_NOISE = 'noise = "0.0007 deg/sqrt(h)"', 'noise = "10 ug/sqrt(Hz)"'
_NONE = (f'bias = "{_G0}"', f'bias = "{_A0}"'), (f'noise = "{_NG0}"', f'noise = "{_NA0}"')


def _grade(bias: tuple[str, str], noise: tuple[str, str], draw: str = "") -> tuple[str, str]:
    return f"{draw}{bias[0]}\n{noise[0]}", f"{draw}{bias[1]}\n{noise[1]}"


#: key -> (label, (gyro table, accel table)); None: the seed's own grade file
GRADES: dict[str, tuple[str, tuple[str, str] | None]] = {
    "seed": ("seed's IMU", None),
    "drawn": ("biases drawn", _grade(_BIAS, _NOISE, 'bias_draw = "random"\n')),
    "biases": ("biases only", _grade(_BIAS, _NONE[1])),
    "noise": ("noise only", _grade(_NONE[0], _NOISE)),
    "gyro": ("gyro noise", _grade(_NONE[0], (_NOISE[0], _NONE[1][1]))),
    "accel": ("accel noise", _grade(_NONE[0], (_NONE[1][0], _NOISE[1]))),
    "ideal": ("ideal IMU", _grade(*_NONE)),
}
ARCMIN = math.radians(1.0 / 60.0)


def _case_for(grade: Path | None, tmp: Path, tag: str) -> Path:
    text = CASE.read_text().replace(f'script = "{SCRIPT}"', f'script = "{(CASE.parent / SCRIPT).as_posix()}"')
    if grade is not None:
        text = text.replace('grade = "seed003_vehicle"', f'grade = "{grade.as_posix()}"')
    out = tmp / f"S003b_{tag}.toml"
    out.write_text(text)
    return out


def _end(one: dict, at_s: float) -> tuple[float, float]:
    """Heading error and the filter's heading sigma (arcmin) at ``at_s``, from
    :func:`s003_monte_carlo._one`'s figures of a run."""
    t = one["t"] * 1e-9
    i = min(int(np.searchsorted(t, at_s)), len(t) - 1)
    err = float(one["hdg"][i])
    return err / ARCMIN, abs(err) / max(math.sqrt(float(one["nees_heading"][i])), 1e-12) / ARCMIN


def _wire_rounding(path: Path) -> np.ndarray:
    """Mean of (ICD frame's angle increment - the IMU's), per axis, as a rate in deg/h."""
    with RecordingReader(path) as r:
        sent = r.read_columnar("/imu")
        _, _, data = r.read_chunks("/wire/imu/tx")
    wire, _ = imu_codec.decode_frames(data)
    n = min(len(wire), len(sent))
    dt = float(np.median(np.diff(sent["t_ns"]))) * 1e-9
    return np.degrees((wire["dtheta"][:n] - sent["dtheta"][:n]).mean(axis=0) / dt) * 3600.0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--grades", default="seed,drawn,biases,noise,ideal", help=f"of {','.join(GRADES)}")
    ap.add_argument("--at", type=float, default=590.0, help="time of the end-of-drive figures, s")
    args = ap.parse_args()
    keys = args.grades.split(",")
    if unknown := [k for k in keys if k not in GRADES]:
        ap.error(f"unknown grade(s) {', '.join(unknown)}; expected some of {', '.join(GRADES)}")
    grades = {GRADES[k][0]: GRADES[k][1] for k in keys}
    seeds = list(range(1, args.runs + 1))
    print(f"S003b with_conversion, seeds 1-{args.runs}: heading consistency by IMU")
    with tempfile.TemporaryDirectory() as tmpd:
        tmp = Path(tmpd)
        seed_args = [a for s in seeds for a in ("--seed", str(s))]
        procs = launch(grades, lambda g, tag: _case_for(g, tmp, tag), tmp, ["--variant", "with_conversion", *seed_args])
        print(f"  {'IMU':<13} {'heading NEES in band':>20} {'error at ' + format(args.at, '.0f') + ' s':>24} "
              f"{'sigma':>7}  {'wire rounding x, y, z':>24}")
        print(f"  {'':<13} {'before':>9} {'after':>10} {'mean':>12} {'RMS':>11} {'there':>7}  {'deg/h':>24}")
        for label, k, p in procs:
            _, err = p.communicate()
            rec = tmp / f"out{k}" / "recordings" / "S003b"
            paths = [rec / f"S003b-with_conversion-s{s}.mcap" for s in seeds]
            if not all(x.exists() for x in paths):
                sys.stderr.write(err)
                raise SystemExit(f"{label}: a run left no recording (exit {p.returncode})")
            one = [_one(x, 60.0) for x in paths]
            ends = np.array([_end(o, args.at) for o in one])
            pre = 100 * np.mean([o["nees_heading_pre"] for o in one])
            post = 100 * np.mean([o["nees_heading_post"] for o in one])
            rounding = _wire_rounding(paths[0])
            print(f"  {label:<13} {pre:8.1f}% {post:9.1f}% {ends[:, 0].mean():+11.2f}' "
                  f"{math.sqrt(np.mean(ends[:, 0] ** 2)):10.2f}' {np.median(ends[:, 1]):6.2f}'  "
                  + " ".join(f"{x:+.5f}" for x in rounding))
    return 0


if __name__ == "__main__":
    sys.exit(main())
