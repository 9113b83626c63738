"""Physical bounds of configuration values, one table for the whole bench.

Every value a user writes passes :func:`check` with the kind of quantity it is where it
enters the bench (a test case, a scenario, a parameter set, a fault schedule), so a run
stays finite in memory and time whatever the files say. The bounds are far beyond any
real use; a value outside them is a typing slip (``"1e300 s"``, ``monte_carlo =
1000000000``, ``every = "1 ns"``), refused with the file, the key, the value and the bound::

    case.toml: scenario.duration: expected a duration <= 2.592e+06 s (30 days), found '1e300 s'

``docs/test_cases.md`` lists the table for users.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from bench.errors import ConfigError
from bench.units import quantity

__all__ = ["Bound", "BOUNDS", "MAX_DURATION_S", "bound", "check", "bounded_quantity", "markdown_table"]

#: The longest run, scenario or fault window the bench takes: 30 days.
MAX_DURATION_S = 30 * 86_400.0


@dataclass(frozen=True)
class Bound:
    """The allowed range of one kind of value (SI, or a plain count).

    ``low``/``high`` are inclusive unless ``low_open``; ``zero`` also allows exactly 0
    below ``low`` (a period of 0 means "once"). ``unit`` and ``scale`` show the bounds in
    messages (``value_SI / scale`` in ``unit``); ``note`` says it in words; ``where``
    lists the keys it holds (for the docs).
    """

    what: str
    low: float | None
    high: float | None
    unit: str = ""
    low_open: bool = False
    zero: bool = False
    scale: float = 1.0
    note: str = ""
    where: str = ""

    def _show(self, x: float) -> str:
        v, unit = x / self.scale, self.unit
        if unit == "s" and 0 < abs(v) < 1:
            v, unit = v * 1e3, "ms"
        text = f"{v:.0f}" if float(v).is_integer() and abs(v) < 1e15 else f"{v:.6g}"
        return f"{text} {unit}" if unit else text

    def text(self) -> str:
        """The range in words, e.g. ``0 or 1 ms .. 2.592e+06 ms (0: once)``."""
        lo = None if self.low is None else self._show(self.low)
        hi = None if self.high is None else self._show(self.high)
        if lo is not None and hi is not None:
            rng = f"> {lo} and <= {hi}" if self.low_open else f"{lo} .. {hi}"
        elif lo is not None:
            rng = f"{'>' if self.low_open else '>='} {lo}"
        else:
            rng = f"<= {hi}"
        return ("0 or " if self.zero else "") + rng + (f" ({self.note})" if self.note else "")

    def violation(self, x: float) -> str | None:
        """What is wrong with ``x`` (``expected ...``), or None when it is inside."""
        if isinstance(x, float) and not math.isfinite(x):
            return f"expected {self.what} as a finite number"
        if self.zero and x == 0:
            return None
        if self.low is not None and (x < self.low or (self.low_open and x == self.low)):
            op = ">" if self.low_open else ">="
            zero = " of 0 or" if self.zero else ""
            return f"expected {self.what}{zero} {op} {self._show(self.low)}"
        if self.high is not None and x > self.high:
            note = f" ({self.note})" if self.note else ""
            return f"expected {self.what} <= {self._show(self.high)}{note}"
        return None


_MS = 1e-3
_MiB = float(1 << 20)

#: kind -> bound. Kinds: durations and times of a run (s), rates (Hz), counts, sizes.
BOUNDS: dict[str, Bound] = {
    "duration": Bound("a duration", 0.0, MAX_DURATION_S, "s", low_open=True, note="30 days",
                      where="`[scenario] duration`, segment durations and a script's total, `[plant] duration`, "
                      "fault `duration`, `[clock] step`"),
    "time": Bound("a time", 0.0, MAX_DURATION_S, "s", note="30 days",
                  where="bench times: fault `start`/`end`, `[[command]] at`, window and track `start`/`end`"),
    "offset": Bound("a time offset", -MAX_DURATION_S, MAX_DURATION_S, "s", note="30 days",
                    where="time parameters of faults (`delay`, `jitter`, `gap`, `ramp`) and sensors"),
    "timeout": Bound("a timeout", 0.0, 3600.0, "s", low_open=True, note="1 hour",
                     where="`[dut]` start-up and shutdown timeouts, `[clock]` timeout and budgets, serial "
                     "`write_timeout`"),
    "period": Bound("a period", _MS, MAX_DURATION_S, "s", zero=True, note="30 days",
                    where="what repeats a fault: `garbage` `every`, synthetic `bad_frames` `every` (0: once)"),
    "events": Bound("a number of fault events per window", 0, 1_000_000,
                    where="window length / `every` of a periodic fault"),
    "rate": Bound("a rate", 0.0, 10_000.0, "Hz", low_open=True,
                  where="`[dut] output_rate`, sensor rates, `[truth] internal_rate`, `[plant] command_rate`"),
    "imu_rate": Bound("an IMU rate", 1.0, 1000.0, "Hz", note="the ICD's IMU frame rates", where="`[imu] rate`"),
    "runs": Bound("a number of runs", 1, 10_000, where="`[run] monte_carlo`, the length of `seeds`"),
    "seed": Bound("a seed", 0, 2**63 - 1, note="2^63 - 1", where="`[run] seeds`, `first_seed`"),
    "points": Bound("a number of truth points", 1, 100_000_000, note="27.7 h at 1 kHz",
                    where="a motion script's duration x `[truth] internal_rate`, a plant's duration / `step`"),
    "repeat": Bound("a repeat count", 1, 100_000, where="segment `repeat`"),
    "segments": Bound("a number of segments", 1, 100_000, note="after repeats", where="a motion script"),
    "burst": Bound("a burst length", 1, 65_536, "bytes", where="`garbage` `length`"),
    "copies": Bound("a number of copies", 1, 100, where="`duplicate` `copies`"),
    "count": Bound("a count", 0, 1_000_000_000, where="`counter_skip` `skip`"),
    "baud": Bound("a baud rate", 1, 10_000_000, "baud",
                  where="`baud_mismatch` `baud`, serial `baudrate`, `[dut.links]` baud and bit rates"),
    "speed_factor": Bound("a speed factor", 0.0, 1000.0, low_open=True, where="`[clock] speed`"),
    "text_file": Bound("a text file size", 0, 64 * _MiB, "MiB", scale=_MiB,
                       where="TOML and CSV inputs: cases, scenarios, parameter sets, fault, mapping, vehicle, "
                       "track files; road networks (GeoJSON)"),
    "log_file": Bound("a log file size", 0, 1024 * _MiB, "MiB", scale=_MiB, where="field logs given to `bench replay`"),
    "json_file": Bound("a JSON file size", 0, 256 * _MiB, "MiB", scale=_MiB,
                       where="results records (`bench compare`, `bench report`), `campaign.json` and run records, "
                       "a JSON DUT configuration file (`bench replay --dut-config`)"),
    "nesting": Bound("a nesting depth", 1, 64, note="arrays and tables inside each other",
                     where="every TOML and JSON input"),
    "nav_file": Bound("a .nav or STD file size", 0, 256 * _MiB, "MiB", scale=_MiB, where="`bench import-nav`"),
    "nav_lines": Bound("a number of lines", 1, 1_000_000, note="and 10 kHz x (the run's duration + 1 s)",
                       where="a .nav or STD file given to `bench import-nav`"),
    "line_length": Bound("a line length", 1, 4096, "bytes", where="a line of a .nav or STD file"),
}


def bound(kind: str) -> Bound:
    """The bound of ``kind`` (KeyError names the known kinds)."""
    try:
        return BOUNDS[kind]
    except KeyError:
        raise KeyError(f"no bound {kind!r}; known: {', '.join(BOUNDS)}") from None


def check(kind: str, value: float, *, file: str | None = None, key: str | None = None, shown: Any = None) -> float:
    """Return ``value`` if it is inside the bound of ``kind``, else raise ConfigError.

    ``shown`` is the value as the user wrote it (``'1e300 s'``), for the message.
    """
    why = bound(kind).violation(value)  # ints compare exactly, however large
    if why is not None:
        found = shown if shown is not None else value
        raise ConfigError(f"{why}, found {found!r}", file=file, key=key)
    return value


def bounded_quantity(
    value: Any, dimension: str, unit: str, kind: str, *, file: str | None = None, key: str | None = None
) -> float:
    """:func:`bench.units.quantity` then :func:`check` (for loaders that read raw tables)."""
    return check(kind, quantity(value, dimension, unit, file=file, key=key), file=file, key=key, shown=value)


def markdown_table(kinds: tuple[str, ...] | None = None) -> str:
    """The bounds as a Markdown table (for the docs)."""
    rows = ["| value | allowed | where |", "|---|---|---|"]
    for k in kinds or tuple(BOUNDS):
        b = BOUNDS[k]
        rows.append(f"| {b.what} | {b.text()} | {b.where} |")
    return "\n".join(rows)
