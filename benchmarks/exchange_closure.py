"""How well the i2Nav export closes: the whole S000 drive exported, integrated outside the bench.

Synthesizes S000 (3600 s, seed000 IMU grade), exports it with ``bench export --format i2nav
--imu ideal`` (the error-free increments, so what is measured is the file format, frames,
Euler angles and time base, not the IMU's errors), integrates ``imu.txt`` with the tests'
own forward-right-down / north-east-down strapdown (tests/exchange/strapdown_frd.py, which
uses nothing of ``bench.nav``) from the first line of ``truth.nav``, and prints the largest
horizontal and vertical errors against ``truth.nav`` and the export's time.

    .venv/bin/python benchmarks/exchange_closure.py
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> None:
    from bench.cli import main as bench
    from tests.exchange.test_closure import _integrate

    with tempfile.TemporaryDirectory() as d:
        rec, folder = Path(d) / "s000.mcap", Path(d) / "x"
        if bench(["synth", "S000", "-o", str(rec), "-q", "--imu-grade", "seed000"]) != 0:
            raise SystemExit("bench synth failed")
        t0 = time.perf_counter()
        if bench(["export", str(rec), "-o", str(folder), "--imu", "ideal"]) != 0:
            raise SystemExit("bench export failed")
        t_export = time.perf_counter() - t0
        imu, nav = np.loadtxt(folder / "imu.txt"), np.loadtxt(folder / "truth.nav")
        err = _integrate(imu, nav)
    horizontal = np.hypot(err[:, 0], err[:, 1])
    print(f"S000 exported ({len(imu)} IMU lines, {len(nav)} truth lines) in {t_export:.1f} s")
    print(f"independent FRD/NED strapdown over {imu[-1, 0] - imu[0, 0]:.0f} s: largest horizontal error "
          f"{horizontal.max() * 1e3:.1f} mm, largest vertical {np.abs(err[:, 2]).max() * 1e3:.1f} mm "
          f"(acceptance: 1 m)")


if __name__ == "__main__":
    main()
