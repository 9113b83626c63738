"""``bench import-nav`` and ``bench score`` of what it writes hold little per line of the
result (issue 32: a 10-million-line ``.nav`` took 6.9 GB to import and 7 GB to score).

Each command runs as its own process on a result of N and of 4N lines (with its STD file)
imported onto a 90 s recording; its peak resident memory (its own ``VmHWM``) gives the
memory each added line costs. The recording reader's cache of decompressed chunks (a
constant, at most 64 MiB) is switched off in the children so that it does not fill up
between the two sizes and pass for memory that grows with the file. Asserted:

* each command costs less than 500 bytes a line (57b1bce: about 820 for the import, 800
  for scoring; now about 220 and 300);
* extrapolated to the largest result the bench accepts (1,000,000 lines), with the cache
  back, each stays under 1 GiB.

No time is measured; the whole takes seconds (benchmarks/import_nav_memory.py measures
the largest result itself).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bench.exchange.i2nav_text import nav_rows
from bench.exchange.nav_import import run_clock
from bench.scoring.data import load_run

HERE = Path(__file__).resolve().parent.parent
DRIVE = HERE / "data" / "short_drive.toml"
CASE = HERE / "run" / "data" / "short_dr.toml"
#: ``bench`` with the recording reader's chunk cache off (see the module docstring), writing
#: its own peak resident memory (VmHWM: this process image's, whatever its parent's was) to
#: the file named by its first argument
BENCH = [sys.executable, "-c", """
import sys
import bench.record.index as index
from bench.cli import main

index._CACHE_BYTES = 0
try:
    code = main(sys.argv[2:])
finally:
    with open("/proc/self/status") as f, open(sys.argv[1], "w") as out:
        out.write(next(line for line in f if line.startswith("VmHWM:")).split()[1])
sys.exit(code)
"""]
CACHE = 64 << 20
N = 25_000
LARGEST = 1_000_000  # bench.exchange.i2nav_text.MAX_LINES
PER_LINE = 500  # bytes


def _peak(*args: str, cwd: Path) -> int:
    """Run ``bench ARGS`` (it must import or judge: exit 0 or 1); its peak resident memory,
    bytes (VmHWM: a child's ``ru_maxrss`` would count its parent's memory at the fork)."""
    hwm = cwd / "hwm.txt"
    p = subprocess.run([*BENCH, str(hwm), *args], cwd=cwd, capture_output=True, text=True)
    assert p.returncode in (0, 1), (args, p.stdout[-2000:], p.stderr[-2000:])
    return int(hwm.read_text()) * 1024


def _result(run: Path, n: int, nav: Path, std: Path) -> None:
    """``n`` epochs spread over the run, each the truth sample before it, and their STD lines."""
    clock, _ = run_clock(run)
    truth = load_run(run).require_truth()
    step = int(truth["t_ns"][-1] - truth["t_ns"][0]) // n // 1000 * 1000  # on the wire's microsecond
    t = truth["t_ns"][0] + np.arange(n, dtype=np.int64) * step
    tr = truth[np.searchsorted(truth["t_ns"], t, side="right") - 1]
    cols, fmts = nav_rows(tr["lat"], tr["lon"], tr["h"], tr["vel_n"], tr["euler"][:, 2], tr["euler"][:, 1],
                          tr["euler"][:, 0])
    fmt = " ".join(f"%{f}" for f in fmts)
    sow = clock.sow_text(t)
    nav.write_text("".join(f"{clock.week} {s} {fmt % tuple(c)}\n" for s, c in zip(sow, cols.tolist(), strict=True)))
    std.write_text("".join(f"{s} 1.0 1.0 2.0 0.05 0.05 0.05 0.0083 0.0083 0.0167\n" for s in sow))


@pytest.fixture(scope="module")
def grown(tmp_path_factory) -> dict[str, tuple[int, int]]:
    """Peak memory of import-nav and of score at N and 4N lines: {command: (peak N, peak 4N)}."""
    d = tmp_path_factory.mktemp("memory")
    run = d / "run.mcap"
    subprocess.run([*BENCH, str(d / "hwm.txt"), "synth", str(DRIVE), "-o", str(run), "-q"], cwd=d, check=True,
                   capture_output=True)
    peaks: dict[str, list[int]] = {"import": [], "score": []}
    for n in (N, 4 * N):
        nav, std, out = d / f"r{n}.nav", d / f"r{n}.std", d / f"r{n}.mcap"
        _result(run, n, nav, std)
        peaks["import"].append(_peak("import-nav", str(nav), "--std", str(std), "--run", str(run), "-o", str(out),
                                     cwd=d))
        peaks["score"].append(_peak("score", str(out), "--case", str(CASE), cwd=d))
    return {k: (v[0], v[1]) for k, v in peaks.items()}


@pytest.mark.parametrize("command", ["import", "score"])
def test_memory_per_line_of_the_result_is_small(grown, command):
    small, large = grown[command]
    per_line = (large - small) / (3 * N)
    assert per_line < PER_LINE, f"{command}: {per_line:.0f} bytes a line ({small >> 20} MiB at {N} lines, " \
                                f"{large >> 20} MiB at {4 * N})"


@pytest.mark.parametrize("command", ["import", "score"])
def test_the_largest_result_accepted_stays_under_1_gib(grown, command):
    small, large = grown[command]
    per_line = max(0.0, (large - small) / (3 * N))
    predicted = large + per_line * (LARGEST - 4 * N) + CACHE
    assert predicted < 1 << 30, f"{command}: {predicted / 2**20:.0f} MiB predicted at {LARGEST} lines"
