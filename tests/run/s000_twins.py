"""The S000 case files, shortened, for the S000-external tests (tests/run/test_s000_external.py).

:func:`shortened` writes a copy of a case file of ``test_cases/`` that runs only the
first ``duration_s`` of its drive (``[scenario] duration``, with the ``[case] shortened``
reason the schema asks for), its scenario path made absolute; ``convergence_s`` moves
the converged window into the shortened run; ``can`` replaces the CAN link. Text edits
of the file as it is shipped, so what runs is the shipped case, not a rewrite of it.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bench.record.mcap_io import RecordingReader

ROOT = Path(__file__).resolve().parents[2]
CASES = ROOT / "test_cases"
EXTERNAL = CASES / "S000_external.toml"
IN_PROCESS = CASES / "S000_sins_doppler.toml"
DOPPLER_ID = 0x130


def _sub(pattern: str, repl: str, text: str, what: str) -> str:
    new, n = re.subn(pattern, repl, text, count=1, flags=re.M)
    if n != 1:
        raise AssertionError(f"the case file has no {what} to edit ({pattern!r})")
    return new


def shortened(src: Path, folder: Path, *, duration_s: float, convergence_s: float | None = None,
              can: str | None = None) -> Path:
    """A copy of case ``src`` in ``folder`` that runs ``duration_s`` (see the module docstring)."""
    text = src.read_text()
    text = _sub(r'^script = "scenarios/', f'script = "{CASES}/scenarios/', text, "[scenario] script")
    text = _sub(r"^\[scenario\]$", f'[scenario]\nduration = "{duration_s:g} s"', text, "[scenario] table")
    text = _sub(r"^\[case\]$", '[case]\nshortened = "a test: alignment and the first minutes of driving"', text,
                "[case] table")
    if convergence_s is not None:
        text = _sub(r'^convergence = ".*"$', f'convergence = "{convergence_s:g} s"', text, "[scoring] convergence")
    if can is not None:
        text = _sub(r"^can = \{.*\}$", f"can = {can}", text, "[dut.links] can")
    out = folder / src.name
    out.write_text(text)
    return out


def nav(path: Path) -> dict[str, np.ndarray]:
    """The DUT's NAV_SOLUTION and NAV_QUALITY records of a recording, without their
    arrival times (which depend on how the DUT was reached)."""
    r = RecordingReader(path)
    out = {}
    for topic in ("/dut/nav_solution", "/dut/nav_quality"):
        rec = r.read_columnar(topic)
        out[topic] = rec[[n for n in rec.dtype.names if n != "rx_ns"]]
    return out


def sensor_inputs(path: Path) -> tuple[np.ndarray, bytes]:
    """The DOPPLER frames and the IMU line's bytes a run sent (the same recording's inputs)."""
    r = RecordingReader(path)
    can = r.read_columnar("/wire/can/tx")
    dop = can[can["can_id"] == DOPPLER_ID][["t_ns", "data"]]
    _, _, buf = r.read_chunks("/wire/imu/tx")
    return dop, buf.tobytes()


#: NAV_SOLUTION quantization (ICD 2.2): SI units of the decoded records per field.
QUANTUM = {"lat": np.radians(1e-7), "lon": np.radians(1e-7), "h": 1e-3, "vel_n": 1e-4,
           "heading": np.radians(1e-7), "pitch": np.radians(1e-7), "roll": np.radians(1e-7)}


def differences(a: np.ndarray, b: np.ndarray) -> str:
    """Where two NAV_SOLUTION record arrays differ, in output quanta (for failure messages)."""
    if len(a) != len(b):
        return f"{len(a)} epochs against {len(b)}"
    lines = []
    for name in a.dtype.names:
        d = np.abs(a[name].astype(np.float64) - b[name].astype(np.float64))
        d = d.reshape(len(a), -1).max(axis=1)
        bad = np.flatnonzero(d > 0)
        if bad.size:
            q = QUANTUM.get(name)
            size = f"{d.max() / q:.2f} quanta" if q else f"{d.max():g}"
            lines.append(f"{name}: {bad.size} epochs differ, first at t = {a['t_ns'][bad[0]] / 1e9:.2f} s, "
                         f"at most {size}")
    return "; ".join(lines) or "identical"


BENCH = [sys.executable, "-c", "import sys; from bench.cli import main; sys.exit(main())"]
HANG_S = 900.0  # a hang guard of a whole shortened run (a loaded machine is slower, never failed)


def bench_run(case: Path, out: Path, *args: str, ns: str | None = None) -> tuple[int, str, dict]:
    """``bench run`` of ``case`` into ``out`` (in the network namespace ``ns``): exit code,
    output, results; fails the test on a hang, a traceback or no results."""
    cmd = [*(["ip", "netns", "exec", ns] if ns else []), *BENCH, "run", str(case), "-o", str(out), "-q",
           "--no-plots", *args]
    # this checkout's bench, in ``bench run`` and the DUT it starts (which inherits the
    # environment): from the case's folder the venv's editable install would be imported,
    # which in a git worktree is another checkout's
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=HANG_S, cwd=case.parent,
                           env={**os.environ, "COLUMNS": "200", "PYTHONPATH": path})
    except subprocess.TimeoutExpired as exc:
        pytest.fail(f"bench run {case.name} did not end within {HANG_S:g} s (hangs?): {exc.stdout}")
    text = p.stdout + p.stderr
    assert "Traceback" not in text, text
    assert (out / "results.json").is_file(), f"bench run {case.name} exited {p.returncode} without results:\n{text}"
    return p.returncode, text, json.loads((out / "results.json").read_text())


def recording(out: Path) -> Path:
    """The one recording of a run's output folder."""
    (rec,) = sorted((out / "recordings").glob("*/*.mcap"))
    return rec


def criteria(results: dict) -> dict[str, tuple[str, float | None]]:
    """criterion id -> (verdict, value) of a one-case results record (negative controls,
    which judge another variant, left out)."""
    (case,) = results["cases"]
    return {c["id"]: (c["verdict"], c["value"]) for c in case["criteria"] if not c.get("control")}
