"""How well a [track] import of the smartLoc Berlin drive agrees with the car's own sensors.

The ground truth (``smartloc_berlin_potsdamer_platz_gt.txt``, positions only) is fitted
with :class:`~bench.scenario.track.SampledTrajectory` and its truth is evaluated at the
times of the car's ``odom3`` records (the same time base: both files start at 0 s and
share their sample times). Two misfits against the car's sensors:

* **yaw rate**: the truth's body rate about the vehicle's up axis (``omega_ib_b[:, 2]``,
  RFU, positive turning left, what a z gyro reads) against the car's yaw-rate sensor
  (``wz``, rad/s, same sign convention), RMS in deg/s;
* **forward speed**: the truth's speed (``|vel_n|``) against the car's speed (``vx``),
  RMS in m/s.

``old`` is the fit as it was before glitch rejection and stationary holds (plain
least-squares quintic smoothing spline, 5 cm, the documented setting): 3.82 deg/s and
0.170 m/s. ``new`` is the [track] table's defaults (:class:`~bench.scenario.track_fit.TrackFit`):
1.78 deg/s and 0.152 m/s. The odom3 records are a copy of the
input file's ``odom3`` lines (``tests/data/smartloc_berlin_potsdamer_platz_odom.txt``).

    PYTHONPATH=. .venv/bin/python benchmarks/track_berlin_fit.py [--method old|new|both] [--report]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from bench.scenario.track import SampledTrajectory, Track, read_smartloc
from bench.scenario.track_fit import TrackFit
from bench.scenario.trajectory import truth_at

DATA = Path(__file__).resolve().parent.parent / "tests" / "data"
GT = DATA / "smartloc_berlin_potsdamer_platz_gt.txt"
ODOM = DATA / "smartloc_berlin_potsdamer_platz_odom.txt"


def read_odom(path: Path = ODOM) -> np.ndarray:
    """(N, 3): time (s), forward speed ``vx`` (m/s), yaw rate ``wz`` (rad/s) of ``odom3`` lines."""
    rows = [line.split() for line in path.read_text().splitlines() if line.startswith("odom3")]
    a = np.array([[float(r[1]), float(r[2]), float(r[7])] for r in rows])
    return a


def misfit(traj: SampledTrajectory, odom: np.ndarray) -> tuple[float, float]:
    """(yaw-rate RMS deg/s, forward-speed RMS m/s) of the trajectory against the car."""
    t = odom[:, 0] - traj.time_offset_s
    t = t[(t >= 0.0) & (t <= traj.duration_s)]
    sel = np.isin(odom[:, 0] - traj.time_offset_s, t)
    tru = truth_at(traj, np.round(t * 1e9).astype(np.int64))
    yaw = np.degrees(tru.omega_ib_b[:, 2] - odom[sel, 2])
    speed = np.linalg.norm(tru.vel_n, axis=1) - odom[sel, 1]
    return math.sqrt(float(np.mean(yaw**2))), math.sqrt(float(np.mean(speed**2)))


def fit(track: Track, method: str) -> SampledTrajectory:
    """The track fitted the ``old`` way (plain spline, 5 cm) or with the defaults (``new``)."""
    if method == "old":
        return SampledTrajectory(track, smoothing=0.05, huber=0.0, reject=0.0, stop_speed=0.0, turn_radius=0.0)
    return SampledTrajectory(track, **TrackFit().kwargs())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--method", choices=("old", "new", "both"), default="both")
    ap.add_argument("--report", action="store_true", help="print the fit report of each fit")
    args = ap.parse_args()
    track = read_smartloc(GT)
    odom = read_odom()
    for method in ("old", "new") if args.method == "both" else (args.method,):
        traj = fit(track, method)
        yaw, speed = misfit(traj, odom)
        print(f"{method}: yaw-rate RMS misfit {yaw:.2f} deg/s, forward-speed RMS misfit {speed:.3f} m/s")
        if args.report:
            for line in traj.fit_report.lines():
                print("  " + line)


if __name__ == "__main__":
    main()
