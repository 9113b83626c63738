"""GPS time of bench times: the time base of the exchange files.

The i2Nav tools (KF-GINS, OB_GINS) stamp every line with GNSS seconds of week and, in
``.nav`` files, the GNSS week. The bench's time base is bench time (ns since scenario
start) with the UTC of bench time zero in ``run_start.epoch_utc_ns``. GPS time is UTC plus
the leap seconds at the run's start (held for the whole run: a run that spans a leap
second is off by one second after it), counted from 1980-01-06 00:00:00 UTC.

Seconds of week are counted from the start of the GPS week in which the run starts, and
keep counting past 604800 s if the run crosses the week's end (so every file of a run
shares one week number and its times never wrap).
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass

import numpy as np

from bench.errors import ConfigError

__all__ = ["GpsClock", "leap_seconds", "WEEK_S"]

WEEK_S = 604_800
_GPS_ZERO_UTC_NS = int(_dt.datetime(1980, 1, 6, tzinfo=_dt.UTC).timestamp()) * 10**9

#: GPS - UTC in seconds from each date on (IERS Bulletin C)
_LEAPS = [
    ((1981, 7, 1), 1), ((1982, 7, 1), 2), ((1983, 7, 1), 3), ((1985, 7, 1), 4), ((1988, 1, 1), 5),
    ((1990, 1, 1), 6), ((1991, 1, 1), 7), ((1992, 7, 1), 8), ((1993, 7, 1), 9), ((1994, 7, 1), 10),
    ((1996, 1, 1), 11), ((1997, 7, 1), 12), ((1999, 1, 1), 13), ((2006, 1, 1), 14), ((2009, 1, 1), 15),
    ((2012, 7, 1), 16), ((2015, 7, 1), 17), ((2017, 1, 1), 18),
]


def leap_seconds(utc_ns: int) -> int:
    """GPS minus UTC, whole seconds, at UTC ``utc_ns`` (ns since 1970)."""
    if utc_ns < _GPS_ZERO_UTC_NS:
        raise ConfigError(f"the run's epoch {utc_ns} ns (UTC) lies before GPS time zero (1980-01-06)")
    out = 0
    for (y, m, d), n in _LEAPS:
        if utc_ns >= int(_dt.datetime(y, m, d, tzinfo=_dt.UTC).timestamp()) * 10**9:
            out = n
    return out


@dataclass(frozen=True)
class GpsClock:
    """Bench time <-> (GPS week, seconds of week) for one run.

    ``week`` is the GPS week at bench time zero; ``zero_ns`` the GPS time of bench time
    zero in ns since the start of that week.
    """

    week: int
    zero_ns: int
    leap_s: int

    @classmethod
    def of_epoch(cls, epoch_utc_ns: int) -> GpsClock:
        """The clock of a run whose bench time zero is UTC ``epoch_utc_ns``."""
        leap = leap_seconds(int(epoch_utc_ns))
        gps_ns = int(epoch_utc_ns) + leap * 10**9 - _GPS_ZERO_UTC_NS
        week = gps_ns // (WEEK_S * 10**9)
        return cls(int(week), int(gps_ns - week * WEEK_S * 10**9), leap)

    def sow_ns(self, t_ns: np.ndarray) -> np.ndarray:
        """Seconds of week of bench times, as integer ns (int64)."""
        return np.asarray(t_ns, dtype=np.int64) + np.int64(self.zero_ns)

    def sow_text(self, t_ns: np.ndarray) -> list[str]:
        """Seconds of week as exact decimal text with 9 decimals (no float rounding)."""
        s = self.sow_ns(t_ns)
        return [f"{v // 10**9}.{v % 10**9:09d}" for v in s.tolist()]

    def bench_ns(self, week: np.ndarray | int, sow_s: np.ndarray) -> np.ndarray:
        """Bench times (int64 ns) of GPS ``week`` and seconds of week (rounded to 1 ns)."""
        weeks = np.asarray(week, dtype=np.int64) - self.week
        ns = np.rint(np.asarray(sow_s, dtype=np.float64) * 1e9).astype(np.int64)
        return weeks * np.int64(WEEK_S * 10**9) + ns - np.int64(self.zero_ns)
