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
import os
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from bench.config.bounds import bound
from bench.config.files import open_bounded, read_blocks
from bench.errors import ConfigError

__all__ = [
    "rfu_to_frd",
    "frd_to_rfu",
    "enu_to_ned",
    "write_columns",
    "nav_rows",
    "std_rows",
    "read_table",
    "iter_table",
    "count_lines",
    "max_lines",
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


def frd_to_rfu(v: np.ndarray) -> np.ndarray:
    """Body vectors (..., 3) from forward-right-down to right-forward-up (the inverse of
    :func:`rfu_to_frd`, which is its own inverse)."""
    return rfu_to_frd(v)


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


#: Largest .nav or STD file, bytes; longest line; most lines (and see :func:`max_lines`).
NAV_FILE_LIMIT = int(bound("nav_file").high or 0)
LINE_LIMIT = int(bound("line_length").high or 0)
MAX_LINES = int(bound("nav_lines").high or 0)
#: The highest output rate the bench takes of a DUT (the bound of ``[dut] output_rate``), Hz.
MAX_RATE_HZ = float(bound("rate").high or 0)
#: Data rows per block of :func:`iter_table` (a multiple of the importer's 50-epoch batches).
BLOCK_ROWS = 164 * 50


def max_lines(duration_ns: int | None) -> tuple[int, str]:
    """The most lines a .nav or STD file of a run of ``duration_ns`` may have, and why: at
    most :data:`MAX_RATE_HZ` over the run and the 1 s after it, and never more than
    :data:`MAX_LINES` (what the bench imports and scores in under 1 GB)."""
    if duration_ns is not None and duration_ns >= 0:
        seconds = duration_ns * 1e-9 + 1.0
        by_rate = math.ceil(seconds * MAX_RATE_HZ - 1e-6)
        if by_rate < MAX_LINES:
            return by_rate, (f"of a {duration_ns * 1e-9:g} s run may have ({MAX_RATE_HZ / 1e3:g} kHz, the highest "
                             "output rate the bench takes, over the run and 1 s after it)")
    return MAX_LINES, "may have (what the bench imports and scores in under 1 GB)"


def count_lines(path: str | Path, *, what: str, limit: int, why: str = "may have") -> int:
    """The number of lines of a regular file of at most :data:`NAV_FILE_LIMIT` bytes (a last
    line without a newline counted), or :class:`ConfigError` when there are more than
    ``limit`` (``why`` says where the limit comes from). Reads the file at C speed only."""
    fd, file = open_bounded(path, what=what, limit=NAV_FILE_LIMIT)
    n, last = 0, b"\n"
    try:
        for chunk in read_blocks(fd, file, what=what, limit=NAV_FILE_LIMIT, size=1 << 20):
            n += chunk.count(b"\n")
            last = chunk[-1:]
            if n > limit:
                break
    finally:
        os.close(fd)
    n += last != b"\n"
    if n > limit:
        raise ConfigError(f"more than the {limit:,} lines {_a(what)} {why}", file=file)
    return n


def _lines(path: str | Path, what: str) -> Iterator[tuple[int, list[bytes]]]:
    """(number of the first line, lines) of the file, in blocks, each line at most
    :data:`LINE_LIMIT` bytes (else ConfigError naming the line)."""
    fd, file = open_bounded(path, what=what, limit=NAV_FILE_LIMIT)
    tail = b""
    lineno = 1
    try:
        for chunk in read_blocks(fd, file, what=what, limit=NAV_FILE_LIMIT, size=1 << 20):
            lines = (tail + chunk).split(b"\n")
            tail = lines.pop()
            if lines and max(map(len, lines)) > LINE_LIMIT:
                k = next(i for i, ln in enumerate(lines) if len(ln) > LINE_LIMIT)
                raise ConfigError(f"line {lineno + k}: longer than the {LINE_LIMIT} bytes a line may have", file=file)
            if len(tail) > LINE_LIMIT:
                raise ConfigError(f"line {lineno + len(lines)}: longer than the {LINE_LIMIT} bytes a line may have",
                                  file=file)
            for i in range(0, len(lines), BLOCK_ROWS):
                yield lineno + i, lines[i : i + BLOCK_ROWS]
            lineno += len(lines)
    finally:
        os.close(fd)
    if tail:
        yield lineno, [tail]


def _a(what: str) -> str:
    return f"{'an' if what[:1] in 'aeiou' or what.startswith('STD') else 'a'} {what}"


def _token(t: bytes) -> str:
    return repr(t[:40].decode("utf-8", "replace"))


def _parse(block: list[tuple[int, list[bytes]]], names: Sequence[str], file: str) -> tuple[np.ndarray, np.ndarray]:
    """The rows (n, k) and line numbers (n,) of the data lines ``block`` holds."""
    k = len(names)
    tokens: list[bytes] = []
    numbers: list[int] = []
    for lineno, line in block:
        if b"#" in line:
            line = line.split(b"#", 1)[0]
        if b"%" in line:
            line = line.split(b"%", 1)[0]
        parts = line.replace(b",", b" ").split()
        if not parts:
            continue
        if len(parts) < k:
            raise ConfigError(f"line {lineno}: expected {k} columns ({', '.join(names)}), found {len(parts)}",
                              file=file)
        tokens += parts[:k]
        numbers.append(lineno)
    try:
        rows = np.array(tokens, dtype=np.float64).reshape(-1, k)
    except ValueError:  # find the first one, as Python reads numbers
        rows = np.empty((len(numbers), k))
        for j, t in enumerate(tokens):
            try:
                rows.flat[j] = float(t)
            except ValueError:
                raise ConfigError(f"line {numbers[j // k]}, column {j % k + 1} ({names[j % k]}): expected a number, "
                                  f"found {_token(t)}", file=file) from None
    bad = ~np.isfinite(rows)
    if bad.any():
        j = int(np.flatnonzero(bad.ravel())[0])
        raise ConfigError(f"line {numbers[j // k]}, column {j % k + 1} ({names[j % k]}): expected a finite number, "
                          f"found {_token(tokens[j])}", file=file)
    return rows, np.asarray(numbers, dtype=np.int64)


def iter_table(path: str | Path, names: Sequence[str], *, what: str,
               header_lines: int = 0) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Blocks of a whitespace-separated numeric text file whose first ``len(names)`` columns
    are ``names`` (more columns are ignored; ``#`` and ``%`` start comments, blank lines are
    skipped; the first ``header_lines`` lines are skipped whatever they hold): an
    (n, len(names)) float array and the (n,) line numbers (from 1) the rows
    come from, for messages about them; at most :data:`BLOCK_ROWS` lines a block, so the
    file is never held whole.

    Raises :class:`ConfigError` naming the file, the line and the field for a line with too
    few columns, a value that is not a number or not finite, a line longer than
    :data:`LINE_LIMIT` bytes; and naming the file for one that is not a regular file of at
    most :data:`NAV_FILE_LIMIT` bytes.
    """
    for first, lines in _lines(path, what):
        block = [(n, ln) for n, ln in enumerate(lines, start=first) if n > header_lines]
        rows, numbers = _parse(block, names, str(path))
        if len(rows):
            yield rows, numbers


def read_table(path: str | Path, names: Sequence[str], *, what: str,
               header_lines: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The whole of :func:`iter_table` (for small files): rows and line numbers; a file with
    no data line is a :class:`ConfigError`."""
    blocks = list(iter_table(path, names, what=what, header_lines=header_lines))
    if not blocks:
        raise ConfigError(f"no data line in the {what}", file=str(path))
    return np.concatenate([b[0] for b in blocks]), np.concatenate([b[1] for b in blocks])
