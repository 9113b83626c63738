"""The ``batch`` DUT kind's keys of ``[dut]``: a command run on exported files.

    [dut]
    kind = "batch"
    command = ["{python}", "my_filter.py", "{input}", "{output}"]
    timeout = "120 s"        # default 600 s; then the DUT FAILs (killed)
    cwd = "."                # relative to the case file's folder (the default)
    imu = "measured"         # or "ideal": the error-free increments in imu.txt

Placeholders in the command's words: ``{input}`` the folder of exported files
(``docs/exchange.md``), ``{output}`` the ``.nav`` result to write, ``{std}`` the optional
STD file beside it, ``{config}`` a JSON file of ``[dut] config``, ``{python}`` the bench's
interpreter, ``{case_dir}`` the case file's folder. The runner is
:mod:`bench.exchange.batch`.
"""

from __future__ import annotations

import string
from dataclasses import dataclass
from typing import Any

from bench.config.table import Table

__all__ = ["BatchSpec", "parse_batch", "BATCH_PLACEHOLDERS", "BATCH_KEYS"]

BATCH_PLACEHOLDERS = ("input", "output", "std", "config", "python", "case_dir")
BATCH_KEYS = ("timeout", "cwd", "imu")


@dataclass(frozen=True)
class BatchSpec:
    """A batch DUT: its command words (placeholders unexpanded), timeout, working folder
    (None: the case's folder) and the IMU topic exported (``measured`` or ``ideal``)."""

    argv: tuple[str, ...]
    timeout_s: float = 600.0
    cwd: str | None = None
    imu: str = "measured"


def parse_batch(t: Table, kind: str) -> tuple[str | None, BatchSpec | None]:
    """``(command, batch)`` of a ``[dut]`` table: the external DUT's command line (a
    string), or the batch DUT's spec (``command`` an array of words); keys of the batch
    kind on another kind are refused."""
    if kind != "batch":
        for k in BATCH_KEYS:
            if t.has(k):
                raise t.error(k, f"'{k}' is a key of a batch DUT, not of kind {kind!r}")
        return t.str("command"), None
    raw: Any = t.raw("command", required=True, expect="the command as an array of words")
    if not isinstance(raw, list) or not raw or not all(isinstance(w, str) and w for w in raw):
        raise t.error("command", f"expected the command as a non-empty array of words such as "
                      f"[\"{{python}}\", \"filter.py\", \"{{input}}\", \"{{output}}\"], found {raw!r}")
    for word in raw:
        try:
            fields = [f for _, f, _, _ in string.Formatter().parse(word) if f is not None]
        except ValueError as exc:
            raise t.error("command", f"a word does not parse ({exc}): {word!r}") from None
        for f in fields:
            if f not in BATCH_PLACEHOLDERS:
                raise t.error("command", f"unknown placeholder {{{f}}}; expected: "
                              + ", ".join("{" + p + "}" for p in BATCH_PLACEHOLDERS))
    timeout = t.quantity("timeout", "time", "s", 600.0, positive=True, bound="timeout")
    cwd = t.str("cwd")
    imu = t.str("imu", "measured", choices=("measured", "ideal"))
    return None, BatchSpec(tuple(raw), float(timeout), cwd, str(imu))  # type: ignore[arg-type]
