"""The i2Nav text formats (KF-GINS, OB_GINS), column by column; ``docs/exchange.md``.

Frames: body forward-right-down (FRD), navigation north-east-down (NED); the bench's are
right-forward-up (RFU) and east-north-up (ENU), converted here and nowhere else. Times are
GPS seconds of week (:mod:`bench.exchange.gpstime`). Angles in degrees, Euler angles
roll, pitch, yaw of the ZYX sequence (yaw clockwise from north, [0, 360)), which are the
bench's roll, pitch and heading.

=========  ===============================================================================
file       columns
=========  ===============================================================================
IMU        sow, dtheta x y z (rad), dvel x y z (m/s), body FRD, over the interval ending at sow
GNSS .pos  sow, lat (deg), lon (deg), h (m), sigma N, E, D (m)
speed      sow, forward speed (m/s)  (odometer, Doppler radar)
.nav       week, sow, lat (deg), lon (deg), h (m), vel N, E, D (m/s), roll, pitch, yaw (deg)
STD        sow, sigma pos N E D (m), vel N E D (m/s), att roll pitch yaw (deg) [, more ignored]
=========  ===============================================================================
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bench.errors import ConfigError

__all__ = [
    "rfu_to_frd",
    "enu_to_ned",
    "write_columns",
    "nav_rows",
    "std_rows",
    "read_table",
    "NAV_COLUMNS",
    "STD_COLUMNS",
]

NAV_COLUMNS = ("week", "sow", "lat", "lon", "h", "vel_n", "vel_e", "vel_d", "roll", "pitch", "yaw")
STD_COLUMNS = ("sow", "sigma_pos_n", "sigma_pos_e", "sigma_pos_d", "sigma_vel_n", "sigma_vel_e", "sigma_vel_d",
               "sigma_roll", "sigma_pitch", "sigma_yaw")


def rfu_to_frd(v: np.ndarray) -> np.ndarray:
    """Body vectors (..., 3) from right-forward-up to forward-right-down."""
    v = np.asarray(v, dtype=float)
    return np.stack([v[..., 1], v[..., 0], -v[..., 2]], axis=-1)


def enu_to_ned(v: np.ndarray) -> np.ndarray:
    """Navigation vectors (..., 3) from east-north-up to north-east-down (its own inverse)."""
    v = np.asarray(v, dtype=float)
    return np.stack([v[..., 1], v[..., 0], -v[..., 2]], axis=-1)


def write_columns(path: Path, times: Sequence[str], cols: np.ndarray, fmts: Sequence[str],
                  lead: Sequence[str] | None = None) -> int:
    """Write one line per row: ``lead`` (e.g. the week), the time text, then the columns of
    ``cols`` (N, k) with ``fmts`` (k format specs). Returns the number of lines."""
    cols = np.asarray(cols, dtype=float).reshape(len(times), -1) + 0.0  # no "-0.0"
    with open(path, "w", encoding="ascii") as fh:
        for i, t in enumerate(times):
            vals = " ".join(format(float(x), f) for x, f in zip(cols[i], fmts, strict=True))
            fh.write((f"{lead[i]} " if lead is not None else "") + f"{t} {vals}\n")
    return len(times)


def nav_rows(lat: np.ndarray, lon: np.ndarray, h: np.ndarray, vel_enu: np.ndarray, roll: np.ndarray,
             pitch: np.ndarray, heading: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """The value columns (N, 9) of ``.nav`` lines from SI (rad, ENU) and their formats."""
    yaw = np.mod(np.degrees(heading), 360.0)
    cols = np.column_stack([np.degrees(lat), np.degrees(lon), h, enu_to_ned(vel_enu), np.degrees(roll),
                            np.degrees(pitch), yaw])
    return cols, [".11f", ".11f", ".4f", ".5f", ".5f", ".5f", ".9f", ".9f", ".9f"]


def std_rows(sigma_pos_enu: np.ndarray, sigma_vel_enu: np.ndarray, sigma_att_hpr: np.ndarray
             ) -> tuple[np.ndarray, list[str]]:
    """The value columns (N, 9) of STD lines from SI sigmas (E N U; heading pitch roll, rad)."""
    sp, sv, sa = (np.asarray(x, dtype=float) for x in (sigma_pos_enu, sigma_vel_enu, sigma_att_hpr))
    cols = np.column_stack([sp[:, 1], sp[:, 0], sp[:, 2], sv[:, 1], sv[:, 0], sv[:, 2],
                            np.degrees(sa[:, 2]), np.degrees(sa[:, 1]), np.degrees(sa[:, 0])])
    return cols, [".4f"] * 3 + [".5f"] * 3 + [".8f"] * 3


def read_table(path: str | Path, names: Sequence[str], *, what: str, max_bytes: int = 1 << 30
               ) -> tuple[np.ndarray, np.ndarray]:
    """Read a whitespace-separated numeric text file whose first ``len(names)`` columns
    are ``names`` (more columns are ignored; ``#`` and ``%`` start comments, blank lines
    are skipped). Returns an (N, len(names)) float array and the (N,) line numbers (from 1)
    the rows come from, for messages about them.

    Raises :class:`ConfigError` naming the file, the line and the field for a line with
    too few columns, a value that is not a number or not finite, or a file with no line.
    """
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"expected a regular file ({what}), found {'a directory' if p.is_dir() else 'nothing'}",
                          file=str(p))
    if p.stat().st_size > max_bytes:
        raise ConfigError(f"{what} of {p.stat().st_size} B is larger than {max_bytes} B", file=str(p))
    rows: list[list[float]] = []
    numbers: list[int] = []
    with open(p, encoding="utf-8", errors="replace") as fh:
        for lineno, line in enumerate(fh, start=1):
            text = line.split("#", 1)[0].split("%", 1)[0].replace(",", " ").strip()
            if not text:
                continue
            parts = text.split()
            if len(parts) < len(names):
                raise ConfigError(f"line {lineno}: expected {len(names)} columns ({', '.join(names)}), "
                                  f"found {len(parts)}", file=str(p))
            row: list[float] = []
            for k, name in enumerate(names):
                try:
                    v = float(parts[k])
                except ValueError:
                    raise ConfigError(f"line {lineno}, column {k + 1} ({name}): expected a number, "
                                      f"found {parts[k][:40]!r}", file=str(p)) from None
                if not math.isfinite(v):
                    raise ConfigError(f"line {lineno}, column {k + 1} ({name}): expected a finite number, "
                                      f"found {parts[k][:40]!r}", file=str(p))
                row.append(v)
            rows.append(row)
            numbers.append(lineno)
    if not rows:
        raise ConfigError(f"no data line in the {what}", file=str(p))
    return np.asarray(rows, dtype=float), np.asarray(numbers, dtype=np.int64)
