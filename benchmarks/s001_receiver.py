"""The S001 receiver alone: per-axis RMS of the BDS fixes against the antenna truth, per
seed and pooled, beside the seed's driving test (synthesis only, no DUT).

Error = fix minus the true antenna position (lever arm applied to the IMU truth), over
every fix epoch of the S001 route (outage epochs carry no fix).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench.nav import earth
from bench.scenario.loader import load_scenario
from bench.scenario.trajectory import truth_at
from bench.sensors.bds import BDS_PARAMS, BdsReceiver
from bench.sensors.geometry import position_at
from bench.sensors.params import resolve

ROOT = Path(__file__).resolve().parents[1]
SEED_RMS = np.array([0.619, 2.759, 2.437])  # E (longitude), N (latitude), U; 3-D 3.73 m


def errors(traj, seed: int, model: str) -> np.ndarray:
    table = {"model": model, "lever_arm": ["0.5 m", "1.2 m", "1.8 m"], "latency": "80 ms", "time_tag_error": "80 ms"}
    m = BdsReceiver(resolve("bds", table, BDS_PARAMS), seed)
    rec = m.run(traj, 0, traj.duration_ns)["/bds"]
    rec = rec[rec["fix_quality"] > 0]
    lat, lon, h = position_at(truth_at(traj, rec["t_ns"]), m.lever)
    R_M, R_N = earth.radii(lat)
    return np.column_stack([(rec["lon"] - lon) * (R_N + h) * np.cos(lat), (rec["lat"] - lat) * (R_M + h), rec["h"] - h])


def line(label: str, r: np.ndarray) -> str:
    d = 100 * (r / SEED_RMS - 1)
    return f"  {label:>5} {r[0]:7.3f} {r[1]:7.3f} {r[2]:7.3f} {np.linalg.norm(r):7.3f}   " + " ".join(
        f"{x:+5.1f}" for x in d
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--model", default="seed001_driving")
    a = ap.parse_args()
    traj = load_scenario(ROOT / "test_cases" / "scenarios" / "S001_bds_urban.toml").trajectory()
    print(f"S001 receiver alone ({a.model}), RMS per axis, m; seed: {SEED_RMS.tolist()}, 3-D 3.73")
    print(f"  {'seed':>5} {'E':>7} {'N':>7} {'U':>7} {'3-D':>7}   (diff to the seed, %)")
    pooled = []
    for s in range(1, a.seeds + 1):
        e = errors(traj, s, a.model)
        pooled.append(e)
        r = np.sqrt(np.mean(e**2, axis=0))
        print(line(str(s), r))
    e = np.concatenate(pooled)
    r = np.sqrt(np.mean(e**2, axis=0))
    print(line("all", r))


if __name__ == "__main__":
    main()
