"""Shared by the heading-budget benchmarks: one case run per IMU grade, two at a time.

:func:`launch` writes each grade's IMU file (``None``: the case's own grade), asks
``case_for(grade_file, tag)`` for the case file to run, and starts ``bench run`` on it
with ``run_args`` into ``tmp/out<k>``; it returns ``(label, k, process)`` per grade, the
processes started two at a time (one per core) and the last pair still running.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
_CLI = "import sys; from bench.cli import main; sys.exit(main())"


def launch(
    grades: Mapping[str, tuple[str, str] | None],
    case_for: Callable[[Path | None, str], Path],
    tmp: Path,
    run_args: Sequence[str],
) -> list[tuple[str, int, subprocess.Popen[str]]]:
    procs: list[tuple[str, int, subprocess.Popen[str]]] = []
    for k, (label, grade) in enumerate(grades.items()):
        gfile = None
        if grade is not None:
            gfile = tmp / f"imu{k}.toml"
            gfile.write_text(f'name = "{label}"\n[gyro]\n{grade[0]}\n[accel]\n{grade[1]}\n')
        cmd = [sys.executable, "-c", _CLI, "run", str(case_for(gfile, f"g{k}")), "-o", str(tmp / f"out{k}"),
               "--force", "--no-plots", "-q", *run_args]
        procs.append((label, k, subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                                  text=True)))
        if len(procs) % 2 == 0:  # two at a time: one per core
            for *_, p in procs[-2:]:
                p.wait()
    return procs
