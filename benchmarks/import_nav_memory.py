"""Peak memory of `bench import-nav` and of `bench score` on the largest result accepted.

For each of two recordings made with `bench synth` -- the 90 s test drive
(tests/data/short_drive.toml) and a 200 s drive -- it writes the largest `.nav` result the
bench accepts for that run (`bench.exchange.i2nav_text.max_lines`: 10 kHz over the run and
the 1 s after it, at most 1,000,000 lines; 910,000 and 1,000,000 lines here), each epoch
the truth sample before it, with an STD file line at every epoch; then runs, each as its
own process, `bench import-nav RESULT --std STD --run RUN -o OUT` and
`bench score OUT --case tests/run/data/short_dr.toml`, and prints the peak resident memory
of each (the process's own VmHWM, read as it exits) beside the 1 GiB target, and the
wall time (for information only).

    .venv/bin/python benchmarks/import_nav_memory.py [--old DIR] [--lines N]

``--old DIR`` runs the same commands with ``PYTHONPATH=DIR`` as well, for an older bench
(``git archive 57b1bce bench models | tar -x -C DIR``), which accepts any number of lines.
``--lines N`` imports N lines instead of the largest accepted.

Figures (`--old` a 57b1bce tree; 2 cores shared with other jobs, so the times are only
indicative; an STD line at every epoch):

    recording  lines      command     now                  57b1bce
    90 s       910,000    import-nav  481 MiB,  34 s       976 MiB, 149 s
    90 s       910,000    score       504 MiB,  19 s       902 MiB,  15 s
    200 s      1,000,000  import-nav  494 MiB,  23 s      1025 MiB, 210 s
    200 s      1,000,000  score       541 MiB,   8 s       971 MiB,  13 s

Target: under 1 GiB (1024 MiB) for the largest result accepted. The issue's 10,000,000-line
result (490 MB) took 6.9 GB to import and 7 GB to score on 57b1bce; it is now refused at
once, the limit named (docs/exchange.md, "Limits").
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DRIVE_90 = ROOT / "tests" / "data" / "short_drive.toml"
CASE = ROOT / "tests" / "run" / "data" / "short_dr.toml"
TARGET = 1 << 30
DRIVE_200 = """
[scenario]
id = "MEM-200"
title = "200 s drive for the import-nav memory benchmark"

[initial]
latitude = 34.246
longitude = 108.909
height = "380 m"
speed = "10 m/s"
heading = "30 deg"

[[segment]]
kind = "uniform"
duration = "200 s"
"""
#: ``bench`` writing its own peak resident memory (VmHWM) to the file named first
BENCH = [sys.executable, "-c", """
import sys
from bench.cli import main

try:
    code = main(sys.argv[2:])
finally:
    with open("/proc/self/status") as f, open(sys.argv[1], "w") as out:
        out.write(next(line for line in f if line.startswith("VmHWM:")).split()[1])
sys.exit(code)
"""]


def _bench(args: list[str], cwd: Path, env: dict[str, str] | None = None) -> tuple[int, int, float]:
    """Exit code, peak resident memory (bytes) and wall time of ``bench ARGS``."""
    hwm = cwd / "hwm.txt"
    hwm.unlink(missing_ok=True)
    t = time.monotonic()
    p = subprocess.run([*BENCH, str(hwm), *args], cwd=cwd, env=env, capture_output=True, text=True)
    wall = time.monotonic() - t
    if p.returncode not in (0, 1):
        print(f"  bench {' '.join(args[:1])}: exit {p.returncode}: {p.stderr.strip()[-500:]}", file=sys.stderr)
    peak = int(hwm.read_text()) * 1024 if hwm.exists() else 0
    return p.returncode, peak, wall


def _result(run: Path, n: int, nav: Path, std: Path) -> None:
    """``n`` epochs spread over the run, each the truth sample before it, and their STD lines."""
    from bench.exchange.i2nav_text import nav_rows
    from bench.exchange.nav_import import run_clock
    from bench.scoring.data import load_run

    clock, _ = run_clock(run)
    truth = load_run(run).require_truth()
    step = int(truth["t_ns"][-1] - truth["t_ns"][0]) // n // 1000 * 1000
    with open(nav, "w") as fn, open(std, "w") as fs:
        for a in range(0, n, 100_000):
            t = truth["t_ns"][0] + np.arange(a, min(n, a + 100_000), dtype=np.int64) * step
            tr = truth[np.searchsorted(truth["t_ns"], t, side="right") - 1]
            cols, fmts = nav_rows(tr["lat"], tr["lon"], tr["h"], tr["vel_n"], tr["euler"][:, 2], tr["euler"][:, 1],
                                  tr["euler"][:, 0])
            fmt = " ".join(f"%{f}" for f in fmts)
            sow = clock.sow_text(t)
            fn.write("".join(f"{clock.week} {s} {fmt % tuple(c)}\n" for s, c in zip(sow, cols.tolist(), strict=True)))
            fs.write("".join(f"{s} 1.0 1.0 2.0 0.05 0.05 0.05 0.0083 0.0083 0.0167\n" for s in sow))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--old", help="also run an older bench from this source tree (PYTHONPATH)")
    ap.add_argument("--lines", type=int, help="lines to import (default: the largest accepted)")
    args = ap.parse_args()
    from bench.exchange.i2nav_text import max_lines
    from bench.exchange.nav_import import run_clock

    benches = [("now", None)]
    if args.old:
        benches.append(("old", {**os.environ, "PYTHONPATH": str(Path(args.old).resolve())}))
    rows = []
    with tempfile.TemporaryDirectory(prefix="import_nav_memory.") as tmp:
        d = Path(tmp)
        (d / "drive200.toml").write_text(DRIVE_200)
        for label, scenario in (("90 s", DRIVE_90), ("200 s", d / "drive200.toml")):
            run = d / f"run{label.split()[0]}.mcap"
            code, _, _ = _bench(["synth", str(scenario), "-o", str(run), "-q"], d)
            assert code == 0, f"bench synth {scenario} failed"
            _, duration_ns = run_clock(run)
            n = args.lines or max_lines(duration_ns)[0]
            nav, std = d / "result.nav", d / "result.std"
            _result(run, n, nav, std)
            print(f"{label} recording: {n:,} lines ({nav.stat().st_size / 2**20:.0f} MiB .nav, "
                  f"{std.stat().st_size / 2**20:.0f} MiB STD)", flush=True)
            for who, env in benches:
                out = d / f"out-{who}.mcap"
                code, peak, wall = _bench(["import-nav", str(nav), "--std", str(std), "--run", str(run), "-o",
                                           str(out), "--force"], d, env)
                rows.append((label, n, "import-nav", who, code, peak, wall))
                code, peak, wall = _bench(["score", str(out), "--case", str(CASE)], d, env) if out.exists() \
                    else (-1, 0, 0.0)
                rows.append((label, n, "score", who, code, peak, wall))
                for r in rows[-2:]:
                    print(f"  {r[2]:<10} {r[3]:<4} exit {r[4]:>2}  peak {r[5] / 2**20:6.0f} MiB  {r[6]:6.1f} s",
                          flush=True)
    print(f"\n{'recording':<10} {'lines':>10}  {'command':<10} {'bench':<5} {'peak':>10}  {'target':>8}  ok")
    for label, n, cmd, who, code, peak, _ in rows:
        ok = "yes" if 0 < peak < TARGET and code in (0, 1) else "NO"
        print(f"{label:<10} {n:>10,}  {cmd:<10} {who:<5} {peak / 2**20:>6.0f} MiB  {TARGET >> 20:>4} MiB  {ok}")


if __name__ == "__main__":
    main()
