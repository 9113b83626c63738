"""Corrupted DUT output, for the bench's own tests of its integrity checks.

:func:`corrupt_output` breaks the NAV_SOLUTION / NAV_QUALITY records whose time of
validity lies in ``[start, end)`` in one of the ways a faulty DUT breaks its output, as
the bench would record it. The synthetic DUT applies it for its ``[[output]]`` defects of
these kinds, and tests apply it to the records of any recording (:class:`RunData`):

* ``bad_crc`` -- every frame fails its CRC: the records are gone and each frame is a bad
  frame (kind ``crc``, at its arrival time);
* ``out_of_range`` -- latitude 95 deg (valid-flagged), which no NAV_SOLUTION may carry;
* ``counter_stuck`` -- the epoch counter keeps the value of the first corrupted epoch;
  ``counter_skip`` -- it steps by 2 a epoch;
* ``time_frozen`` -- every time of validity is the first corrupted one's;
  ``time_backwards`` -- times of validity run backwards from there;
  ``time_jump`` -- they jump forward by ``amount`` (default 1e6 s);
* ``no_quality`` -- no NAV_QUALITY for these epochs.

The values stay those of the true epoch: only what the corruption names is broken.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["CORRUPTIONS", "corrupt_output"]

CORRUPTIONS = (
    "bad_crc",
    "out_of_range",
    "counter_stuck",
    "counter_skip",
    "time_frozen",
    "time_backwards",
    "time_jump",
    "no_quality",
)
DEFAULT_JUMP_NS = 1_000_000 * 1_000_000_000
_BAD_LATITUDE = math.radians(95.0)


def _span(t: np.ndarray, start_ns: int, end_ns: int | None) -> np.ndarray:
    return (t >= start_ns) & (t < end_ns if end_ns is not None else True)


def _bad(records: np.ndarray, message: str) -> list[dict[str, Any]]:
    return [
        {"t_ns": int(rx), "link": f"can:{message}", "kind": "crc", "detail": f"{message}: bad crc (corrupted)"}
        for rx in records["rx_ns"]
    ]


def corrupt_output(
    nav: np.ndarray,
    quality: np.ndarray | None,
    kind: str,
    start_ns: int,
    end_ns: int | None = None,
    amount_ns: int | None = None,
) -> tuple[np.ndarray, np.ndarray | None, list[dict[str, Any]]]:
    """Corrupted copies of ``nav`` and ``quality`` (records in any order) and the bad
    frames the corruption made (see the module docstring)."""
    if kind not in CORRUPTIONS:
        raise ValueError(f"unknown corruption {kind!r}; expected one of {', '.join(CORRUPTIONS)}")
    nav = nav.copy()
    quality = None if quality is None else quality.copy()
    on = _span(nav["t_ns"], start_ns, end_ns)
    q_on = _span(quality["t_ns"], start_ns, end_ns) if quality is not None else None
    if not on.any():
        return nav, quality, []
    t0 = int(nav["t_ns"][on].min())
    first = nav["epoch"][on][np.argmin(nav["t_ns"][on])]
    bad: list[dict[str, Any]] = []
    if kind == "bad_crc":
        bad = _bad(nav[on], "NAV_SOLUTION")
        nav = nav[~on]
        if quality is not None:
            bad += _bad(quality[q_on], "NAV_QUALITY")
            quality = quality[~q_on]
    elif kind == "out_of_range":
        nav["lat"][on] = np.where(nav["lat"][on] < 0, -_BAD_LATITUDE, _BAD_LATITUDE)
        nav["valid"][on] = 1
    elif kind in ("counter_stuck", "counter_skip"):
        times = np.unique(nav["t_ns"][on])
        for recs, sel in ((nav, on), (quality, q_on)):
            if recs is None:
                continue
            if kind == "counter_stuck":
                recs["epoch"][sel] = first
            else:
                rank = np.searchsorted(times, recs["t_ns"][sel])
                recs["epoch"][sel] = ((recs["epoch"][sel].astype(np.int64) + rank) % 256).astype(np.uint8)
    elif kind == "no_quality":
        if quality is not None:
            quality = quality[~q_on]
    else:
        jump = DEFAULT_JUMP_NS if amount_ns is None else int(amount_ns)
        for recs, sel in ((nav, on), (quality, q_on)):
            if recs is None:
                continue
            t = recs["t_ns"][sel]
            if kind == "time_frozen":
                recs["t_ns"][sel] = t0
            elif kind == "time_backwards":
                recs["t_ns"][sel] = 2 * t0 - t
            else:
                recs["t_ns"][sel] = t + jump
    return nav, quality, bad
