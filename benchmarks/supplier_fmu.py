"""How closely a supplier's FMU, driven through a mapping alone, gives the bench its truth.

Builds the pythonfmu planar car of tests/plant/data/planar (FMI 2.0; east/north in m, yaw
counter-clockwise from east in rad, speed in km/h, yaw rate in deg/s; no units declared),
drives the tests' 30 s scenario (straight, a 20 m loop of more than a full turn, straight)
through ``mapping.toml`` with the FMU's own pose as truth, steps the same FMU directly with
the same held commands, and prints the truth's misfit to the FMU's outputs at every 1 ms
step, and the misfit of the FMU's own rates to its pose that the run measures.

    .venv/bin/python benchmarks/supplier_fmu.py
"""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> None:
    from tests.plant.conftest import DATA, build_pythonfmu
    from tests.plant.test_supplier_fmu import MAPPING, _drive, _position_error

    with tempfile.TemporaryDirectory() as d:
        fmu = build_pythonfmu(DATA / "planar" / "planar_car.py", Path(d))
        run, traj, t, y = _drive(fmu, MAPPING)
        err = _position_error(traj, t, y)
        k = traj.kinematics(t)
    straight = t < 10.0
    heading = 0.5 * math.pi - y[:, 2]
    dh = np.degrees(np.abs(np.angle(np.exp(1j * (k.euler[:, 0] - heading)))))
    dv = np.abs(np.linalg.norm(k.vel_n, axis=1) - y[:, 3] / 3.6)
    print(f"supplier car, {len(t)} steps of 1 ms, truth from the FMU's own position and heading:")
    print(f"  position misfit: straight {err[straight].max():.2e} m, whole drive (loop included) {err.max():.2e} m")
    print(f"  heading misfit: {dh.max():.2e} deg; speed misfit: straight {dv[straight].max():.2e} m/s, "
          f"whole drive {dv.max():.2e} m/s")
    for name, c in run.consistency.items():
        scale = (180 / math.pi) if "heading" in name else 1.0
        unit = "deg/s" if "heading" in name else "m/s"
        print(f"  the FMU's {name} against its pose: RMS {c.rms * scale:.2e} {unit}, max {c.max * scale:.2e} {unit} "
              f"({c.samples} samples)")


if __name__ == "__main__":
    main()
