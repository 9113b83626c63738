"""What every row of the fault matrix checks, and the small inputs the rows edit
(see the package's test modules for the rows)."""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).parent.parent
BENCH = [sys.executable, "-c", "import sys; from bench.cli import main; sys.exit(main())"]
SHORT = HERE / "data" / "short_drive.toml"
SHORT_DR = HERE / "run" / "data" / "short_dr.toml"
MARK = "BENCH_FAULT_MATRIX_MARK"
EXIT_CODES = (0, 1, 2, 3)


@dataclass
class Outcome:
    code: int
    out: str
    err: str

    @property
    def text(self) -> str:
        return self.out + self.err


def _marked(mark: str) -> list[int]:
    """Processes (other than this one) whose environment carries ``mark``."""
    needle = f"{MARK}={mark}".encode()
    found = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit() or int(d.name) == os.getpid():
            continue
        try:
            env = (d / "environ").read_bytes()
            state = (d / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if needle in env.split(b"\0") and state != "Z":
            found.append(int(d.name))
    return found


def bench(*args: str, cwd: Path, timeout: float = 240, ns: str | None = None, fsize: int | None = None,
          expect: int | None = None) -> Outcome:
    """Run ``bench ARGS`` as a user would and check what every row checks (module docstring)."""
    mark = uuid.uuid4().hex
    env = {**os.environ, MARK: mark, "COLUMNS": "200"}
    env.pop("BENCH_TRACEBACK", None)
    cmd = [*(["ip", "netns", "exec", ns] if ns else []), *BENCH, *args]

    def limits() -> None:
        if fsize is not None:  # every write past the limit fails with EFBIG, as on a full disk
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)

    p = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout,
                       preexec_fn=limits if fsize is not None else None)
    outcome = Outcome(p.returncode, p.stdout, p.stderr)
    assert p.returncode in EXIT_CODES, outcome.text
    assert "Traceback" not in outcome.text, outcome.text
    if expect is not None:
        assert p.returncode == expect, outcome.text
    deadline = time.monotonic() + 60.0  # processes being reaped by the kernel (a hang guard)
    while (left := _marked(mark)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not left, f"left running: {left}"
    return outcome


def readable(recording: Path, cwd: Path) -> dict:
    """``bench info --json`` of a recording that must be readable."""
    info = bench("info", str(recording), "--json", cwd=cwd, expect=0)
    return json.loads(info.out)


# ----------------------------------------------------------------------------- inputs
DRIVE = """
[scenario]
id = "T-10"
title = "ten seconds"

[initial]
latitude = 30.0
longitude = 110.0
height = "50 m"
speed = "10 m/s"
heading = "0 deg"

[[segment]]
kind = "uniform"
duration = "{duration}"
{extra}
"""

CASE = """
[case]
id = "M10"
title = "matrix case"
requirements = ["R"]

[scenario]
script = "{script}"

[dut]
kind = "synthetic"

[dut.synthetic]
rate = "100 Hz"
{dut_extra}
[run]
{run}

{faults}
[[criterion]]
id = "H"
requirement = "R"
metric = "accuracy.horizontal.max"
{limit}
"""


def case(folder: Path, name: str = "case.toml", *, script: str = "drive.toml", duration: str = "10 s",
         limit: str = 'at_most = "1 m"', run: str = "seeds = [1]", faults: str = "", dut_extra: str = "",
         extra: str = "") -> Path:
    """A small synthetic-DUT case (10 s drive) with one part replaced."""
    folder.mkdir(parents=True, exist_ok=True)
    if script == "drive.toml":
        (folder / "drive.toml").write_text(DRIVE.format(duration=duration, extra=extra))
    path = folder / name
    path.write_text(CASE.format(script=script, limit=limit, run=run, faults=faults, dut_extra=dut_extra))
    return path
