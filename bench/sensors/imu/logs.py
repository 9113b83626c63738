"""Static IMU logs for characterisation: what a file is, and reading PSINS text logs.

:func:`sniff` looks at a file before anything parses it and names what it found (a
directory, a device, an empty file, binary data, text of another kind, an MCAP
recording, a PSINS log); :func:`read_psins_imu` reads a PSINS SIMU text log; every
refusal is a :class:`~bench.errors.ConfigError` naming the file and what was in it.
:func:`check_log` checks increments however they were read (finite, enough samples);
:func:`static_log` makes one with the bench's own IMU model, to check the analysis by.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.config.files import read_bytes, regular_file
from bench.errors import ConfigError

__all__ = ["ImuLog", "MCAP_MAGIC", "MAX_TEXT_BYTES", "MIN_SAMPLES", "sniff", "read_psins_imu", "check_log",
           "output_resolution", "static_log"]

MCAP_MAGIC = b"\x89MCAP0\r\n"
#: A PSINS text log larger than this is refused (30 min at 100 Hz is 2.7 MB).
MAX_TEXT_BYTES = 512 * 1024 * 1024
_WHAT = "IMU log (a PSINS .imu text log or an MCAP recording)"
#: Fewer samples than this give no Allan deviation worth printing.
MIN_SAMPLES = 100


@dataclass
class ImuLog:
    """Increments of a logged IMU: (N, 3) rad and m/s, interval ``dt`` (s).

    ``gyro_lsb`` and ``accel_lsb`` are the output resolutions (rad, m/s per axis) when
    the file states them; ``g`` the g of the accelerometer's unit the file states (PSINS:
    the header's scale constant, which turns its ug*s LSB into m/s; not the local
    gravity, which follows from ``lat`` and ``h``); ``h`` the height (m) the file states.
    """

    dtheta: np.ndarray
    dvel: np.ndarray
    dt: float
    lat: float | None = None
    source: str = ""
    gyro_lsb: np.ndarray | None = None
    accel_lsb: np.ndarray | None = None
    g: float | None = None
    irregular: int = 0  # sampling intervals that differ from ``dt`` (recordings)
    h: float | None = None


def _describe_bytes(head: bytes) -> str:
    return "binary data (starts " + " ".join(f"{b:02x}" for b in head[:8]) + ")"


def sniff(path: str | Path) -> str:
    """``"mcap"`` or ``"text"`` for a file worth parsing; :class:`ConfigError` naming
    what was found for anything else (missing, directory, device, FIFO, empty, binary,
    too large)."""
    path = regular_file(path, what=_WHAT, limit=MAX_TEXT_BYTES)  # no directory, device, FIFO or huge file
    size = path.stat().st_size
    if size == 0:
        raise ConfigError("empty file; expected an IMU log (PSINS .imu text or an MCAP recording)", file=str(path))
    try:
        with path.open("rb") as fh:
            head = fh.read(4096)
    except OSError as exc:
        raise ConfigError(f"cannot read: {exc.strerror}", file=str(path)) from None
    if head.startswith(MCAP_MAGIC):
        return "mcap"
    if b"\x00" in head:
        raise ConfigError(f"{_describe_bytes(head)}, not a PSINS text log or an MCAP recording", file=str(path))
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(head) - 4:  # not just a character cut at the end of the block
            raise ConfigError(f"{_describe_bytes(head)}, not a PSINS text log or an MCAP recording",
                              file=str(path)) from None
    return "text"


def _first_line(text: str) -> str:
    for line in text.splitlines():
        if line.strip():
            return repr(line.strip()[:60])
    return "nothing but blank lines"


def read_psins_imu(path: str | Path) -> ImuLog:
    """PSINS SIMU text log: ``%`` header lines, three parameter lines, then per sample six
    integers (angle increments in gyro LSB, velocity increments in accelerometer LSB)."""
    path = Path(path)
    file = str(path)
    try:
        text = read_bytes(path, what=_WHAT, limit=MAX_TEXT_BYTES).decode("utf-8")
    except UnicodeDecodeError:
        raise ConfigError("not UTF-8 text; expected a PSINS .imu text log", file=file) from None
    numbered = [(n, ln) for n, ln in enumerate(text.splitlines(), 1) if ln.strip() and not ln.lstrip().startswith("%")]
    lines = [ln for _, ln in numbered]
    if len(lines) < 4:
        raise ConfigError(
            f"not a PSINS IMU log: expected three parameter lines and samples after the % header, found "
            f"{len(lines)} line(s) of other text (first: {_first_line(text)})", file=file)
    try:
        p2 = [float(v) for v in lines[1].split()]
        p3 = [float(v) for v in lines[2].split()]
        lat_deg, h, interval_ms, g = p2[0], p2[2], p2[4], p2[5]
        gyro_arcsec, acc_ugs = np.array(p3[0:3]), np.array(p3[3:6])
        if len(p3) < 6:
            raise IndexError
    except (ValueError, IndexError):
        raise ConfigError(
            "not a PSINS IMU log: parameter lines 2 and 3 are not the PSINS layout "
            "(lat lon h t0 interval_ms g / gyro LSB arcsec x3, accel LSB ug*s x3); found "
            f"{lines[1][:60]!r} and {lines[2][:60]!r}", file=file) from None
    checks = [
        (math.isfinite(lat_deg) and abs(lat_deg) <= 90.0, "latitude (line 2, field 1) within +-90 deg", lat_deg),
        (math.isfinite(interval_ms) and 0.0 < interval_ms <= 1000.0, "sampling interval (line 2, field 5) within "
         "(0, 1000] ms", interval_ms),
        (math.isfinite(g) and 9.7 < g < 9.9, "g of the accelerometer unit (line 2, field 6) within 9.7..9.9 m/s^2",
         g),
        (math.isfinite(h) and abs(h) < 1e5, "height (line 2, field 3) within +-100 km", h),
        (bool(np.all(np.isfinite(gyro_arcsec)) and np.all(gyro_arcsec > 0)), "gyro LSB (line 3) positive",
         list(gyro_arcsec)),
        (bool(np.all(np.isfinite(acc_ugs)) and np.all(acc_ugs > 0)), "accel LSB (line 3) positive", list(acc_ugs)),
    ]
    for ok, what, value in checks:
        if not ok:
            raise ConfigError(f"expected the {what}, found {value}", file=file)
    try:
        data = np.loadtxt(lines[3:], dtype=float, ndmin=2)
    except ValueError as exc:
        for n, ln in numbered[3:]:
            parts = ln.split()
            try:
                if len(parts) != 6 or not all(math.isfinite(float(v)) for v in parts):
                    raise ValueError
            except ValueError:
                raise ConfigError(f"line {n}: expected six numbers (a sample), found {ln.strip()[:60]!r}",
                                  file=file) from None
        raise ConfigError(f"samples are not six numbers per line: {exc}", file=file) from None
    if data.shape[1] != 6:
        raise ConfigError(f"expected six columns per sample, found {data.shape[1]}", file=file)
    gyro_lsb = np.radians(gyro_arcsec / 3600.0)
    acc_lsb = acc_ugs * 1e-6 * g
    log = ImuLog(data[:, 0:3] * gyro_lsb, data[:, 3:6] * acc_lsb, interval_ms * 1e-3, math.radians(lat_deg), file,
                 gyro_lsb, acc_lsb, g, h=h)
    check_log(log)
    return log


def check_log(log: ImuLog) -> None:
    """Refuse increments that give no honest Allan deviation (non-finite, too few)."""
    n = len(log.dtheta)
    if n < MIN_SAMPLES:
        raise ConfigError(f"{n} samples; an Allan deviation needs at least {MIN_SAMPLES}", file=log.source)
    if not (math.isfinite(log.dt) and log.dt > 0.0):
        raise ConfigError(f"sampling interval {log.dt!r} s is not positive", file=log.source)
    for name, x in (("angle", log.dtheta), ("velocity", log.dvel)):
        bad = ~np.isfinite(x).all(axis=1)
        if bad.any():
            raise ConfigError(f"non-finite {name} increment in sample {int(np.argmax(bad))}", file=log.source)


def output_resolution(x: np.ndarray) -> float | None:
    """The pulse size of quantized increments (every value a whole multiple of it), or
    None when the data are not quantized."""
    x = np.abs(np.asarray(x, dtype=float))
    v = np.unique(x[:100_000])  # the pulse from a sample, then checked on every value
    if len(v) < 2 or len(v) > 10_000:
        return None
    q = float(np.min(np.diff(v)))
    if not q > 0.0:
        return None
    k = x / q
    if np.all(np.abs(k - np.round(k)) <= 1e-6 * np.maximum(1.0, k)):
        return q
    return None


def static_log(
    grade: str, rate_hz: float, duration_s: float, *, seed: int = 1, lat: float = 0.6, heading: float = 0.5
) -> ImuLog:
    """A static log through the bench's IMU error model.

    The unit stands level at latitude ``lat`` (rad), height 0, facing ``heading`` (rad,
    clockwise from north; the default gives every gyro a share of the Earth rate): its
    exact increments are the Earth rate and normal gravity times the interval, to which
    :class:`~bench.sensors.imu.errors.ImuErrorModel` adds the errors of ``grade`` (a
    name in ``models/imu`` or a path) with ``seed``, block by block.
    """
    from bench.nav import earth
    from bench.sensors.imu.errors import ImuErrorModel
    from bench.sensors.imu.grade import load_grade
    from bench.sensors.imu.ideal import ImuBlock

    g = load_grade(grade)
    T = 1.0 / rate_hz
    n = round(duration_s * rate_hz)
    period = round(1e9 / rate_hz)
    right = np.array([math.cos(heading), -math.sin(heading), 0.0])  # body axes RFU in ENU
    forward = np.array([math.sin(heading), math.cos(heading), 0.0])
    omega = np.array([right, forward, [0.0, 0.0, 1.0]]) @ earth.earth_rate_n(lat) * T
    force = np.array([0.0, 0.0, float(earth.gravity(lat, 0.0))]) * T
    model = ImuErrorModel(g, seed, rate_hz)
    dth, dv = np.empty((n, 3)), np.empty((n, 3))
    for k0 in range(0, n, 1 << 18):
        k1 = min(n, k0 + (1 << 18))
        m = k1 - k0
        block = ImuBlock(np.arange(k0 + 1, k1 + 1, dtype=np.int64) * period, np.tile(omega, (m, 1)),
                         np.tile(force, (m, 1)), np.full(m, 0x3F, np.uint8))
        out = model.apply(block)
        dth[k0:k1], dv[k0:k1] = out.dtheta, out.dvel
    return ImuLog(dth, dv, T, lat, f"static {g.name} at {rate_hz:g} Hz, seed {seed}")
