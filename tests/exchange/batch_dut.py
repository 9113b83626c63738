"""A batch DUT for the bench's tests: reads the exported files, writes a .nav result.

    batch_dut.py INPUT OUTPUT MODE

MODE ``truth``: the exported truth with small deterministic errors (a "good" estimator,
plus an STD file); ``fail``: exits with code 3; ``garbage``: writes a malformed line;
``nothing``: exits 0 without a result; ``hang``: sleeps (for the timeout); ``flood``: as
``truth`` but the first second's epochs written 300 times (30,000 epochs within a second).
"""

import math
import sys
import time
from pathlib import Path


def main() -> int:
    inp, out, mode = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3]
    if mode == "fail":
        print("fatal: no GNSS fix to initialise from", file=sys.stderr)
        return 3
    if mode == "hang":
        time.sleep(60)
        return 0
    if mode == "nothing":
        return 0
    if mode == "garbage":
        out.write_text("2369 18.0 34.2 108.9 380.0 0 0 0 0 0 not-a-number\n")
        return 0
    rows, std = [], []
    for k, line in enumerate((inp / "truth.nav").read_text().splitlines()):
        c = line.split()
        week, sow = c[0], c[1]
        lat, lon, h = float(c[2]), float(c[3]), float(c[4])
        # 0.5 m north-east error wandering slowly, 0.01 deg heading error
        d = 0.5 * math.sin(0.01 * k)
        lat += d / 6.37e6 * 180 / math.pi
        yaw = (float(c[10]) + 0.01) % 360.0
        rows.append(f"{week} {sow} {lat:.11f} {lon:.11f} {h:.4f} {c[5]} {c[6]} {c[7]} {c[8]} {c[9]} {yaw:.9f}")
        std.append(f"{sow} 1.0 1.0 2.0 0.05 0.05 0.05 0.02 0.02 0.05")
    if mode == "flood":  # the first second's epochs 300 times over: 30,000 epochs within a second
        rows = [r for k, r in enumerate(rows) for _ in range(300 if k < 100 else 1)]
    out.write_text("\n".join(rows) + "\n")
    out.with_name("result_std.txt").write_text("\n".join(std) + "\n")
    print(f"wrote {len(rows)} epochs")
    return 0


if __name__ == "__main__":
    sys.exit(main())
