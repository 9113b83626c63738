"""Field logs in the formats engineers have, made into the lines' byte streams for ``bench replay``.

``bench replay --imu-log/--gnss-log`` re-emits what a logger kept on the ``imu`` and
``gnss`` lines (:mod:`bench.run.logreplay`). A log in another format is read here and
converted: IMU increments into ICD 3 frames at the log's own rate (each increment rounded
to the ICD's 1e-9 rad and 1e-8 m/s with the remainder carried to the next frame, so the
sum of what is sent is the sum of the log to half an LSB), GNSS fixes into the ICD 4 NMEA
epochs. Formats, frames, units and time bases are in ``docs/exchange.md`` ("Field logs in
other formats"):

==============  ==================================================================================
IMU format      file
==============  ==================================================================================
``icd``         the ``imu`` line's bytes (ICD 3 frames), re-emitted untouched
``psins``       PSINS SIMU text (``.imu``): header LSBs, g and interval; body right-forward-up
``kfgins``      KF-GINS / OB_GINS ``imu.txt``: GPS sow, increments forward-right-down
``gnss-ins-sim`` its output folder (``time.csv``, ``gyro-N.csv``, ``accel-N.csv``): rates, FRD
``declared``    any text/CSV log with a TOML declaration beside it (``LOG.toml``)
==============  ==================================================================================

==============  ==================================================================================
GNSS format     file
==============  ==================================================================================
``nmea``        the ``gnss`` line's bytes (NMEA 0183), re-emitted untouched
``kfgins``      KF-GINS ``gnss.pos``: GPS sow, lat, lon (deg), h (m), sigma N, E, D (m)
==============  ==================================================================================

Time: a log stamped in GPS seconds of week (KF-GINS, a declared ``gps_sow`` log) or UTC (a
declared ``utc`` log) puts bench time zero at the whole second at or before the start of
its first IMU interval; the UTC of bench time zero (the epoch) then follows from the log,
given the GPS week, which seconds of week do not carry: ``--gps-week``, the week column of
a KF-GINS ``truth.nav`` given as the truth, or ``--epoch`` (which must then agree with the
log to the millisecond). A log with times of its own only (PSINS, gnss-ins-sim, a declared
``bench`` log) starts its first interval at bench time zero; its epoch is ``--epoch`` or,
failing that, the bench's default, said loudly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.config.files import read_toml, regular_file
from bench.errors import CodecError, ConfigError
from bench.exchange.gpstime import WEEK_S, leap_seconds
from bench.exchange.i2nav_text import NAV_COLUMNS, frd_to_rfu, read_table
from bench.nav import earth
from bench.scenario.track import Track
from bench.sensors.imu.logs import ImuLog, check_log, read_psins_imu
from bench.wire.imu import (
    DTHETA_LSB,
    DVEL_LSB,
    FRAME_SIZE,
    STATUS_ALL_VALID,
    carry_quantize,
    decode_frames,
    encode_frames,
)
from bench.wire.imu_stream import accept_frames
from bench.wire.nmea import GNSS_FIX_DTYPE, encode_epochs

__all__ = ["IMU_FORMATS", "GNSS_FORMATS", "ImuSamples", "FieldConversion", "read_imu_log", "icd_stream",
           "imu_log_for_allan", "read_gnss_log", "truth_nav_track", "convert_field_logs", "GPS_ZERO_UTC_NS",
           "DECLARATION_KEYS"]

IMU_FORMATS = {
    "icd": "the imu line's bytes (ICD 3 frames)",
    "psins": "PSINS SIMU text log (.imu)",
    "kfgins": "KF-GINS/OB_GINS imu.txt (GPS sow, forward-right-down increments)",
    "gnss-ins-sim": "gnss-ins-sim output (its folder, or gyro-N.csv beside accel-N.csv and time.csv)",
    "declared": "a text/CSV log declared by a TOML file beside it (LOG.toml)",
}
GNSS_FORMATS = {
    "nmea": "the gnss line's bytes (NMEA 0183)",
    "kfgins": "KF-GINS gnss.pos (GPS sow, lat, lon, h, sigma N E D)",
}
GPS_ZERO_UTC_NS = 315_964_800 * 10**9  # 1980-01-06T00:00:00Z
_SEC = 10**9
#: Time bases of the IMU samples: a time of their own, GPS seconds of week, UTC seconds since 1970.
TIME_BASES = ("bench", "gps_sow", "utc")
#: The keys a declaration TOML may hold (docs/exchange.md, "Declaring a log").
DECLARATION_KEYS = ("columns", "skip_lines", "time_column", "time_unit", "time_base", "gyro_columns", "gyro_unit",
                    "accel_columns", "accel_unit", "axes", "g")
_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
# unit -> (scale to SI, is a rate)
_GYRO_UNITS = {"rad": (1.0, False), "deg": (math.pi / 180, False), "rad/s": (1.0, True),
               "deg/s": (math.pi / 180, True), "deg/h": (math.pi / 180 / 3600, True)}
_ACCEL_UNITS = {"m/s": (1.0, False), "m/s^2": (1.0, True), "g": (float("nan"), True), "g*s": (float("nan"), False)}
# bench RFU = M @ log vector
_AXES = {
    "RFU": np.eye(3),
    "FRD": np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]),
    "FLU": np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
}


@dataclass
class ImuSamples:
    """IMU increments read from a log, in the bench's body frame (right-forward-up).

    ``t_ns`` (N,) int64: end of each sample's interval in the log's time base
    (``time_base``: ``bench`` a time of its own, ns; ``gps_sow`` GPS seconds of week, ns;
    ``utc`` ns since 1970); ``dt_ns`` the interval before the first sample;
    ``dtheta``, ``dvel`` (N, 3) rad and m/s. ``lines`` (N,) the file line of each sample
    (0 when not from a line), for messages.
    """

    fmt: str
    source: str
    t_ns: np.ndarray
    dtheta: np.ndarray
    dvel: np.ndarray
    dt_ns: int
    time_base: str = "bench"
    lines: np.ndarray | None = None
    psins: ImuLog | None = None  # the PSINS log as read (its header's LSBs, g, latitude)
    notes: list[str] = field(default_factory=list)

    @property
    def rate_hz(self) -> float:
        return 1e9 / self.dt_ns


@dataclass
class FieldConversion:
    """What :func:`convert_field_logs` made of the logs: the lines' bytes (None: the log was
    the line's bytes already or not given), the epoch it found (None: none), how, the truth
    track (bench-time seconds) of a ``truth.nav``, figures and warnings."""

    imu_data: bytes | None = None
    gnss_data: bytes | None = None
    imu_format: str = ""
    gnss_format: str = ""
    epoch_ns: int | None = None
    epoch_rule: str | None = None
    truth: Track | None = None
    figures: dict[str, object] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


def _how_to() -> str:
    forms = "; ".join(f"{k}: {v}" for k, v in IMU_FORMATS.items())
    return (f"the IMU log formats are {forms}. Choose one with --imu-format, or declare the log's columns, units, "
            "axes and time base in a TOML file beside it (docs/exchange.md, 'Declaring a log')")


def _declaration(path: Path) -> Path | None:
    for cand in (path.with_suffix(".toml"), path.with_name(path.name + ".toml")):
        if cand != path and cand.is_file():
            return cand
    return None


def _head(path: Path, n: int = 4096) -> bytes:
    try:
        with path.open("rb") as fh:
            return fh.read(n)
    except OSError as exc:
        raise ConfigError(f"cannot read: {exc.strerror}", file=str(path)) from None


def _numbers(line: str) -> list[float] | None:
    parts = line.replace(",", " ").split()
    try:
        return [float(p) for p in parts] if parts else None
    except ValueError:
        return None


def sniff_imu(path: Path) -> str:
    """The IMU format of ``path`` by its content (module docstring), or ConfigError naming
    what was found and how to declare a log."""
    if path.is_dir():
        if (path / "time.csv").is_file() and any(path.glob("gyro-*.csv")):
            return "gnss-ins-sim"
        raise ConfigError(f"a folder without gnss-ins-sim output (time.csv, gyro-N.csv); {_how_to()}", file=str(path))
    regular_file(path, what="IMU log")  # no FIFO, device or huge file is opened
    if _declaration(path) is not None:
        return "declared"
    head = _head(path)
    if accept_frames(np.frombuffer(head, np.uint8))[0].size:
        return "icd"
    text = head.decode("utf-8", "replace")
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    if (lines and lines[0].startswith("%")) or path.suffix.lower() == ".imu":  # PSINS's header, or its extension
        return "psins"
    if lines and "gyro_x (" in lines[0]:
        return "gnss-ins-sim"
    data = [_numbers(ln) for ln in lines[:5] if not ln.startswith("#")]
    if data and all(d is not None and len(d) == 7 for d in data[:-1]) and data[0] and 0 <= data[0][0] <= 2 * WEEK_S:
        return "kfgins"
    from bench.run.bytelogs import describe

    raise ConfigError(f"not an IMU log the bench reads: no ICD IMU frame, found {describe(_head(path, 1 << 20))}; "
                      + _how_to(), file=str(path))


def _times_ns(seconds: np.ndarray, scale: float = 1.0) -> np.ndarray:
    return np.rint(np.asarray(seconds, np.float64) * (scale * 1e9)).astype(np.int64)


def _check_times(t_ns: np.ndarray, lines: np.ndarray | None, file: str) -> None:
    if len(t_ns) < 2:
        raise ConfigError(f"{len(t_ns)} IMU sample(s); a log needs at least two", file=file)
    bad = np.flatnonzero(np.diff(t_ns) <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        where = f"line {int(lines[k])}" if lines is not None and lines[k] else f"sample {k}"
        raise ConfigError(f"{where}: time {t_ns[k] / 1e9:.9f} s is not later than the sample before "
                          f"({t_ns[k - 1] / 1e9:.9f} s)", file=file, key="time")


def _kfgins_imu(path: Path) -> ImuSamples:
    names = ("sow", "dtheta_x", "dtheta_y", "dtheta_z", "dvel_x", "dvel_y", "dvel_z")
    rows, lines = read_table(path, names, what="KF-GINS IMU file")
    t = _times_ns(rows[:, 0])
    _check_times(t, lines, str(path))
    return ImuSamples("kfgins", str(path), t, frd_to_rfu(rows[:, 1:4]), frd_to_rfu(rows[:, 4:7]),
                      int(np.median(np.diff(t))), "gps_sow", lines)


def _psins(path: Path) -> ImuSamples:
    log = read_psins_imu(path)
    dt_ns = round(log.dt * 1e9)
    n = len(log.dtheta)
    # X-right, Y-forward, Z-up: the bench's own body axes
    return ImuSamples("psins", str(path), np.arange(1, n + 1, dtype=np.int64) * dt_ns, log.dtheta, log.dvel, dt_ns,
                      "bench", None, log)


def _rates_to_increments(t_ns: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """Increments over (t[k-1], t[k]] of rates sampled at ``t`` (trapezoid), k >= 1."""
    dt = np.diff(t_ns).astype(np.float64)[:, None] * 1e-9
    return 0.5 * (rate[1:] + rate[:-1]) * dt


def _csv_columns(path: Path, expected: tuple[str, ...], what: str) -> np.ndarray:
    """The columns of a gnss-ins-sim CSV (a header line ``name (unit),...``), in SI as
    named by ``expected`` (``name (unit)`` each)."""
    head = _head(path, 1024).decode("utf-8", "replace").splitlines()
    header = [h.strip() for h in head[0].split(",")] if head else []
    if header[: len(expected)] != list(expected):
        raise ConfigError(f"line 1: expected the gnss-ins-sim header {','.join(expected)}, found "
                          f"{','.join(header)[:120]!r}", file=str(path))
    rows, _ = read_table(path, [h.split(" (")[0] for h in expected], what=what, header_lines=1)
    return rows


def _gnss_ins_sim_imu(path: Path) -> ImuSamples:
    folder = path if path.is_dir() else path.parent
    k = "0"
    if not path.is_dir() and "-" in path.stem:
        k = path.stem.rsplit("-", 1)[1]
    files = {n: folder / f"{n}-{k}.csv" for n in ("gyro", "accel")} | {"time": folder / "time.csv"}
    for name, p in files.items():
        if not p.is_file():
            raise ConfigError(f"gnss-ins-sim output without {p.name} (the {name} of run {k})", file=str(folder))
    t = _csv_columns(files["time"], ("time (sec)",), "gnss-ins-sim time file")[:, 0]
    gyro = _csv_columns(files["gyro"], ("gyro_x (deg/s)", "gyro_y (deg/s)", "gyro_z (deg/s)"),
                        "gnss-ins-sim gyro file")
    acc = _csv_columns(files["accel"], ("accel_x (m/s^2)", "accel_y (m/s^2)", "accel_z (m/s^2)"),
                       "gnss-ins-sim accel file")
    if not len(t) == len(gyro) == len(acc):
        raise ConfigError(f"time.csv has {len(t)} rows, gyro-{k}.csv {len(gyro)}, accel-{k}.csv {len(acc)}: "
                          "not one run's output", file=str(folder))
    t_ns = _times_ns(t)
    _check_times(t_ns, np.arange(2, len(t) + 2), str(files["time"]))
    dth = _rates_to_increments(t_ns, np.radians(gyro))
    dv = _rates_to_increments(t_ns, acc)
    return ImuSamples("gnss-ins-sim", str(folder), t_ns[1:] - t_ns[0], frd_to_rfu(dth), frd_to_rfu(dv),
                      int(np.median(np.diff(t_ns))), "bench", np.arange(3, len(t) + 2))


def _declared_imu(path: Path) -> ImuSamples:
    decl_path = _declaration(path)
    if decl_path is None:
        raise ConfigError(f"--imu-format declared needs a TOML declaration beside the log ({path.stem}.toml); "
                          + _how_to(), file=str(path))
    decl_file = str(decl_path)
    d = read_toml(decl_path, what="IMU log declaration")
    d = d.get("imu_log", d)
    unknown = sorted(set(d) - set(DECLARATION_KEYS))
    if unknown:
        raise ConfigError(f"unknown key(s) {', '.join(unknown)}; a declaration holds {', '.join(DECLARATION_KEYS)}",
                          file=decl_file, key=unknown[0])

    def need(key: str, kind: type, choices=None):
        if key not in d:
            raise ConfigError("missing (docs/exchange.md, 'Declaring a log')", file=decl_file, key=key)
        v = d[key]
        if not isinstance(v, kind) or (choices is not None and v not in choices):
            want = f"one of {', '.join(choices)}" if choices else kind.__name__
            raise ConfigError(f"expected {want}, found {v!r}", file=decl_file, key=key)
        return v

    columns = need("columns", list)
    if not columns or not all(isinstance(c, str) and c for c in columns) or len(set(columns)) != len(columns):
        raise ConfigError("expected a list of distinct column names", file=decl_file, key="columns")
    skip = d.get("skip_lines", 0)
    if not isinstance(skip, int) or skip < 0:
        raise ConfigError(f"expected a whole number of lines, found {skip!r}", file=decl_file, key="skip_lines")
    t_col = need("time_column", str)
    t_scale = _TIME_UNITS[need("time_unit", str, tuple(_TIME_UNITS))]
    base = d.get("time_base", "bench")
    if base not in TIME_BASES:
        raise ConfigError(f"expected one of {', '.join(TIME_BASES)}, found {base!r}", file=decl_file,
                          key="time_base")
    g_scale, g_rate = _GYRO_UNITS[need("gyro_unit", str, tuple(_GYRO_UNITS))]
    a_scale, a_rate = _ACCEL_UNITS[need("accel_unit", str, tuple(_ACCEL_UNITS))]
    if math.isnan(a_scale):
        g0 = d.get("g", 9.80665)
        if not isinstance(g0, int | float) or not 9.7 < g0 < 9.9:
            raise ConfigError(f"expected the g of the accelerometer unit in 9.7..9.9 m/s^2, found {g0!r}",
                              file=decl_file, key="g")
        a_scale = float(g0)
    if g_rate != a_rate:
        raise ConfigError("the gyro and accelerometer columns must both be increments or both rates",
                          file=decl_file, key="accel_unit")
    axes = d.get("axes", "RFU")
    if isinstance(axes, str) and axes in _AXES:
        m = _AXES[axes]
    else:
        try:
            m = np.array(axes, dtype=float)
        except (TypeError, ValueError):
            m = np.zeros(0)
        if m.shape != (3, 3) or not np.allclose(m @ m.T, np.eye(3), atol=1e-6) or np.linalg.det(m) < 0:
            raise ConfigError(f"expected RFU, FRD, FLU or a 3x3 rotation matrix (rows: the bench's right, forward, "
                              f"up in the log's axes), found {axes!r}", file=decl_file, key="axes")
    sel = {}
    for key in ("gyro_columns", "accel_columns"):
        cols = need(key, list)
        if len(cols) != 3 or any(c not in columns for c in cols):
            raise ConfigError(f"expected three of the columns {columns}, found {cols!r}", file=decl_file, key=key)
        sel[key] = [columns.index(c) for c in cols]
    if t_col not in columns:
        raise ConfigError(f"expected one of the columns {columns}, found {t_col!r}", file=decl_file,
                          key="time_column")
    rows, lines = read_table(path, columns, what="declared IMU log", header_lines=skip)
    t_ns = _times_ns(rows[:, columns.index(t_col)], t_scale)
    _check_times(t_ns, lines, str(path))
    gyro = rows[:, sel["gyro_columns"]] * g_scale
    acc = rows[:, sel["accel_columns"]] * a_scale
    if g_rate:
        gyro, acc, t_out, lines = (_rates_to_increments(t_ns, gyro), _rates_to_increments(t_ns, acc), t_ns[1:],
                                   lines[1:])
    else:
        t_out = t_ns
    dt_ns = int(np.median(np.diff(t_ns)))
    if base == "bench" and not g_rate:
        t_out = t_out - t_out[0] + dt_ns
    elif base == "bench":
        t_out = t_out - t_ns[0]
    return ImuSamples("declared", str(path), t_out, gyro @ m.T, acc @ m.T, dt_ns, base, lines,
                      notes=[f"declared by {decl_file}"])


def read_imu_log(path: str | Path, fmt: str | None = None) -> ImuSamples:
    """The increments of an IMU log of format ``fmt`` (None: sniffed); ``icd`` is not read
    here (the bytes go out as they are)."""
    path = Path(path)
    fmt = fmt or sniff_imu(path)
    readers = {"psins": _psins, "kfgins": _kfgins_imu, "gnss-ins-sim": _gnss_ins_sim_imu, "declared": _declared_imu}
    if fmt not in readers:
        raise ConfigError(f"expected one of {', '.join(readers)}, found {fmt!r}", key="--imu-format")
    return readers[fmt](path)


def _icd_samples(path: Path) -> ImuSamples:
    """The frames of an ICD byte log of the imu line, decoded (garbage between them skipped)."""
    from bench.config.files import read_bytes

    buf = np.frombuffer(read_bytes(path, what="IMU byte log"), np.uint8)
    starts, _ = accept_frames(buf)
    if starts.size < 2:
        raise ConfigError(f"{starts.size} ICD IMU frame(s) found; " + _how_to(), file=str(path))
    samples, _ = decode_frames(buf[starts[:, None] + np.arange(FRAME_SIZE)], check=False)
    t = samples["t_ns"].astype(np.int64)
    _check_times(t, None, str(path))
    return ImuSamples("icd", str(path), t, samples["dtheta"].astype(float), samples["dvel"].astype(float),
                      int(np.median(np.diff(t))))


def imu_log_for_allan(path: str | Path, fmt: str | None = None) -> ImuLog:
    """An :class:`ImuLog` (``bench imu allan``) of an IMU log of any format."""
    path = Path(path)
    fmt = fmt or sniff_imu(path)
    s = _icd_samples(path) if fmt == "icd" else read_imu_log(path, fmt)
    if s.psins is not None:
        return s.psins
    steps = np.diff(s.t_ns)
    irregular = int(np.sum(np.abs(steps - s.dt_ns) > 0.01 * s.dt_ns))
    log = ImuLog(s.dtheta, s.dvel, s.dt_ns * 1e-9, None, s.source, irregular=irregular)
    check_log(log)
    return log


def icd_stream(t_ns: np.ndarray, dtheta: np.ndarray, dvel: np.ndarray, *, file: str = "",
               lines: np.ndarray | None = None) -> bytes:
    """ICD 3 frames of increments (RFU) due at bench times ``t_ns``: each rounded to the
    LSB with the remainder carried to the next frame; status all valid, temperature 0."""
    t_ns = np.asarray(t_ns, np.int64)
    if len(t_ns) and t_ns[0] < 0:
        raise ConfigError(f"the first IMU sample lies {-t_ns[0] / 1e9:g} s before bench time zero", file=file)
    n = len(t_ns)
    dth, _ = carry_quantize(dtheta, DTHETA_LSB, np.zeros(3))
    dv, _ = carry_quantize(dvel, DVEL_LSB, np.zeros(3))
    for name, v, lsb in (("angle", dth, DTHETA_LSB), ("velocity", dv, DVEL_LSB)):
        big = np.flatnonzero(np.any(np.abs(np.rint(v / lsb)) > 2**31 - 1, axis=1))
        if big.size:
            k = int(big[0])
            where = f"line {int(lines[k])}" if lines is not None and lines[k] else f"sample {k}"
            raise ConfigError(f"{where}: {name} increment {np.abs(v[k]).max():.6g} does not fit the ICD frame "
                              f"(int32 of {lsb:g}); wrong unit declared?", file=file)
    try:
        frames = encode_frames(t_ns, dth, dv, np.full(n, STATUS_ALL_VALID), np.zeros(n),
                               np.arange(n, dtype=np.int64) % 256)
    except CodecError as exc:
        raise ConfigError(f"cannot encode as ICD IMU frames: {exc}", file=file) from None
    assert frames.shape[1] == FRAME_SIZE
    return frames.tobytes()


# ---------------------------------------------------------------------------------------- GNSS
def sniff_gnss(path: Path) -> str:
    """The GNSS format of ``path`` by its content, or ConfigError naming the formats."""
    if not path.is_file():
        return "nmea"  # refused by the byte-log reader with its own message
    head = _head(path)
    text = head.decode("utf-8", "replace")
    if "$" in text and "*" in text:
        return "nmea"
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    if lines and lines[0].startswith("gps_lat ("):
        raise ConfigError("a gnss-ins-sim GPS file: it has no per-fix sigmas, which the NMEA GST carries and "
                          "estimators weight fixes by; write it as a KF-GINS gnss.pos (sow, lat, lon, h, sigma N E "
                          "D) with the sigmas of its error model", file=str(path))
    data = [_numbers(ln) for ln in lines[:5] if not ln.startswith("#")]
    if data and all(d is not None and len(d) >= 7 for d in data[:-1]) and data[0] and 0 <= data[0][0] <= 2 * WEEK_S:
        return "kfgins"
    return "nmea"  # the NMEA reader names what it found


def read_gnss_log(path: str | Path, fmt: str) -> tuple[np.ndarray, np.ndarray, str]:
    """Fixes of a GNSS log (:data:`GNSS_FIX_DTYPE` without the times), their times (ns in
    the log's time base) and the time base (``gps_sow`` or ``bench``)."""
    path = Path(path)
    if fmt == "kfgins":
        names = ("sow", "lat", "lon", "h", "sigma_n", "sigma_e", "sigma_d")
        rows, lines = read_table(path, names, what="KF-GINS GNSS file")
        t = _times_ns(rows[:, 0])
        base = "gps_sow"
        lat, lon, h = np.radians(rows[:, 1]), np.radians(rows[:, 2]), rows[:, 3]
        sig = rows[:, 4:7]
        vel = np.zeros((len(t), 3))  # not sent (see convert_field_logs)
        notes = lines
    else:
        raise ConfigError(f"expected one of {', '.join(GNSS_FORMATS)}, found {fmt!r}", key="--gnss-format")
    _check_times(t, notes, str(path))
    bad = np.flatnonzero(np.abs(lat) > math.pi / 2)
    if bad.size:
        raise ConfigError(f"line {int(notes[bad[0]])}: latitude {math.degrees(lat[bad[0]]):g} deg beyond +-90",
                          file=str(path), key="lat")
    fixes = np.zeros(len(t), GNSS_FIX_DTYPE)
    fixes["lat"], fixes["lon"], fixes["h"], fixes["vel_n"] = lat, lon, h, vel
    fixes["sigma_lat"], fixes["sigma_lon"], fixes["sigma_alt"] = sig[:, 0], sig[:, 1], np.abs(sig[:, 2])
    fixes["quality"], fixes["sats"], fixes["hdop"] = 1, 0, 0.0
    return fixes, t, base


# ---------------------------------------------------------------------------------------- truth
def truth_nav_track(path: str | Path, zero_gps_ns: int | None) -> tuple[Track, int]:
    """A KF-GINS ``.nav`` file as a :class:`Track` in seconds from GPS time ``zero_gps_ns``
    (ns since 1980-01-06; None: from its first line's), and that zero."""
    rows, lines = read_table(path, NAV_COLUMNS, what="KF-GINS navigation file")
    week = rows[:, 0]
    if np.any(week != np.rint(week)) or np.any(week < 0):
        k = int(np.flatnonzero((week != np.rint(week)) | (week < 0))[0])
        raise ConfigError(f"line {int(lines[k])}, column 1 (week): expected a GPS week, found {week[k]:g}",
                          file=str(path))
    gps_ns = week.astype(np.int64) * (WEEK_S * _SEC) + _times_ns(rows[:, 1])
    zero = int(gps_ns[0]) if zero_gps_ns is None else int(zero_gps_ns)
    lat, lon, h = np.radians(rows[:, 2]), np.radians(rows[:, 3]), rows[:, 4]
    xyz = earth.geodetic_to_ecef(lat, lon, h)
    euler = np.radians(np.column_stack([rows[:, 10], rows[:, 9], rows[:, 8]]))  # heading, pitch, roll
    return Track((gps_ns - zero) * 1e-9, xyz, euler, str(path)), zero


def _first_week(path: Path) -> int:
    rows, _ = read_table(path, NAV_COLUMNS[:2], what="KF-GINS navigation file")
    return int(rows[0, 0])


def _utc_of_gps(gps_ns: int) -> int:
    """UTC (ns since 1970) of a GPS time (ns since 1980-01-06)."""
    approx = GPS_ZERO_UTC_NS + gps_ns
    leap = leap_seconds(approx - 18 * _SEC)
    return approx - leap * _SEC


def _gps_of_utc(utc_ns: int) -> int:
    return utc_ns + leap_seconds(utc_ns) * _SEC - GPS_ZERO_UTC_NS


# ---------------------------------------------------------------------------------------- all
def convert_field_logs(imu: Path | None, gnss: Path | None, *, imu_format: str | None = None,
                       gnss_format: str | None = None, epoch_ns: int | None = None, gps_week: int | None = None,
                       truth: Path | None = None, truth_format: str = "smartloc") -> FieldConversion:
    """Read and convert the field logs (module docstring) and fix the time base."""
    from bench.runinfo import DEFAULT_EPOCH, parse_epoch

    default_epoch_ns, default_epoch_text = parse_epoch(DEFAULT_EPOCH), DEFAULT_EPOCH
    out = FieldConversion()
    samples = None
    if imu is not None:
        fmt = imu_format or sniff_imu(Path(imu))
        out.imu_format = fmt
        if fmt != "icd":
            samples = read_imu_log(imu, fmt)
            out.figures["imu_conversion"] = {"format": fmt, "samples": len(samples.t_ns),
                                             "rate_hz": round(samples.rate_hz, 6), "time_base": samples.time_base}
    fixes = None
    if gnss is not None:
        gfmt = gnss_format or sniff_gnss(Path(gnss))
        out.gnss_format = gfmt
        if gfmt != "nmea":
            fixes, g_t, g_base = read_gnss_log(gnss, gfmt)
    bases = {b for b in ([samples.time_base] if samples is not None else []) + ([g_base] if fixes is not None else [])}
    if len(bases) > 1:
        raise ConfigError(f"the IMU log is timed in {samples.time_base if samples else '?'} and the GNSS log in "
                          f"{g_base}: the bench cannot tie them together; give both in one time base",
                          file=str(gnss))
    base = bases.pop() if bases else None
    zero = 0
    if base in ("gps_sow", "utc"):
        starts = ([int(samples.t_ns[0]) - samples.dt_ns] if samples is not None else []) + (
            [int(g_t[0])] if fixes is not None else [])
        zero = min(starts) // _SEC * _SEC
        if base == "utc":
            epoch = zero
            rule = "the IMU log's UTC times (bench time zero at the whole second before its first interval)"
        else:
            week, how = _week(gps_week, truth, truth_format, epoch_ns, zero, default_epoch_ns, default_epoch_text, out)
            epoch = _utc_of_gps(week * WEEK_S * _SEC + zero)
            rule = (f"the logs' GPS seconds of week with week {week} ({how}); bench time zero at sow "
                    f"{zero // _SEC}")
        if epoch_ns is not None and abs(epoch_ns - epoch) >= 10**6:
            raise ConfigError(
                f"--epoch says bench time zero is {epoch_ns / 1e9:.3f} s since 1970 (UTC), the log's own times "
                f"say {epoch / 1e9:.3f} s ({rule}): drop --epoch, or give the GPS week with --gps-week",
                key="--epoch")
        out.epoch_ns, out.epoch_rule = epoch, rule
    if samples is not None:
        t = samples.t_ns - zero
        out.imu_data = icd_stream(t, samples.dtheta, samples.dvel, file=samples.source, lines=samples.lines)
    if fixes is not None:
        fixes["t_ns"] = g_t - zero
        if out.epoch_ns is not None:
            ep = out.epoch_ns
        elif epoch_ns is not None:
            ep = epoch_ns
        else:
            ep = default_epoch_ns
        fixes["utc_ns"] = fixes["t_ns"] + ep
        keep = fixes["t_ns"] >= 0
        try:
            batch = encode_epochs(fixes[keep])
        except CodecError as exc:
            raise ConfigError(f"cannot encode as NMEA: {exc}", file=str(gnss)) from None
        # gnss.pos has no velocity: only GGA, GST and ZDA go out (RMC and VTG would carry a made-up speed)
        kinds = np.arange(len(batch)) % 5
        sent = [bytes(batch.buf[batch.offsets[k]:batch.offsets[k + 1]]) for k in np.flatnonzero(
            np.isin(kinds, (1, 2, 4)))]
        out.gnss_data = b"".join(sent)
        out.figures["gnss_conversion"] = {"format": out.gnss_format, "fixes": int(keep.sum())}
    if truth is not None and truth_format == "kfgins":
        if base == "gps_sow" and out.epoch_ns is not None:
            z = _gps_of_utc(out.epoch_ns)
        else:
            z = None
            ep = out.epoch_ns if out.epoch_ns is not None else epoch_ns
            if ep is not None:
                z = _gps_of_utc(ep)
        track, _ = truth_nav_track(truth, z)
        if z is None:
            out.warnings.append(f"{truth}: the truth's first line is taken as bench time zero (no log gives the "
                                "GPS time of bench time zero)")
        out.truth = track
    return out


def _week(gps_week: int | None, truth: Path | None, truth_format: str, epoch_ns: int | None, zero_sow: int,
          default_epoch_ns: int, default_text: str, out: FieldConversion) -> tuple[int, str]:
    if gps_week is not None:
        if not 0 <= gps_week < 10_000:
            raise ConfigError(f"expected a GPS week, found {gps_week}", key="--gps-week")
        return gps_week, "--gps-week"
    if truth is not None and truth_format == "kfgins":
        return _first_week(truth), f"the week column of {truth}"
    if epoch_ns is not None:
        gps = _gps_of_utc(epoch_ns) - zero_sow
        return round(gps / (WEEK_S * _SEC)), "the week of --epoch"
    week = _gps_of_utc(default_epoch_ns) // (WEEK_S * _SEC)
    out.warnings.append(
        f"the logs are stamped in GPS seconds of week, which carry no week: the week is ASSUMED to be {week}, the "
        f"week of the bench's default epoch {default_text}; the replay's dates (NMEA, BENCH_EPOCH) are made up. "
        "Give --gps-week, --epoch, or a truth.nav (its week column)")
    return int(week), f"ASSUMED: the default epoch {default_text}"
