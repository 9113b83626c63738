"""The IMU stream's rate, measured from its frames' own times of validity, and checked
against the rate the case or the link declares before a replay runs.

An estimator takes its IMU interval from the frames' times (docs/estimators.md, "The IMU
interval"), so a stream at a rate other than the one the test case was written for runs,
and is judged, as if it were right: the bench refuses it instead (exit 2, both rates
named). The rules (docs/run_engine.md, "The IMU rate of a replay"):

* The measured interval is the median of the gaps between consecutive frames' times of
  validity, each divided by the frames it spans by the frames' counters when the stream
  is ICD bytes (frames lost on the wire skip counter values; gaps of zero or less, a
  repeated or out-of-order frame, do not count), then
  the median again of the gaps up to 1.5 times the first (a lost frame's longer gap left
  out, as the estimators count it: docs/estimators.md). Lost frames and jitter move it
  only when they are the rule.
* The measured interval must lie within :data:`RATE_TOLERANCE` (2 %) of the declared one:
  an IMU's clock is off by a few hundred ppm at most, while the rates the ICD carries
  (1..1000 Hz) that a log is mistaken for differ by far more.
* The rate must hold over the whole stream: the median over each block of
  :data:`BLOCK_GAPS` consecutive gaps must lie within :data:`CHANGE_TOLERANCE` (25 %) of
  the first block's. A stream whose rate changes mid-log is refused, naming the bench time
  and both intervals: an estimator measures its interval once, while it aligns, and takes
  a longer gap for lost frames (docs/estimators.md), so after a rate drop it would
  integrate each frame over the old, shorter interval, silently.
* A stream of fewer than two frames has no measurable rate: nothing to check.

The providers (:class:`~bench.run.replay.RecordingReplay`,
:class:`~bench.run.logreplay.LogReplay`) measure their stream with :func:`measure_stream`
as they are built (refusing a rate change); the CLI checks the result against the rate a
case or ``--imu-rate`` declares with :func:`require_rate`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.config.bounds import bounded_quantity
from bench.errors import ConfigError
from bench.frames import SerialBatch
from bench.wire.imu import FRAME_DTYPE, FRAME_SIZE
from bench.wire.imu_stream import accept_frames

__all__ = [
    "ImuRate",
    "measure_stream",
    "require_rate",
    "frame_times",
    "case_rate",
    "check_replay",
    "RATE_TOLERANCE",
    "CHANGE_TOLERANCE",
    "BLOCK_GAPS",
]

RATE_TOLERANCE = 0.02  # relative difference of the measured from the declared interval
CHANGE_TOLERANCE = 0.25  # relative difference of a block's median interval from the first block's
BLOCK_GAPS = 50  # gaps per block of the rate-change test
_OFFS = np.arange(FRAME_SIZE)


@dataclass(frozen=True)
class ImuRate:
    """The measured rate of an IMU stream: ``interval_ns`` the median gap between
    consecutive frames' times of validity over ``frames`` frames, of ``source``."""

    interval_ns: float
    frames: int
    source: str

    @property
    def rate_hz(self) -> float:
        return 1e9 / self.interval_ns

    def describe(self) -> str:
        return f"{self.rate_hz:.6g} Hz (median interval {self.interval_ns / 1e6:.6g} ms over {self.frames} frames)"


def frame_times(batch: SerialBatch) -> tuple[np.ndarray, np.ndarray]:
    """The times of validity (ns) and the counters of the ICD IMU frames in a serial
    batch's bytes, in the order they go out (the stream decoder's resynchronisation rule)."""
    starts, _ = accept_frames(batch.buf)
    if not starts.size:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    rec = batch.buf[starts[:, None] + _OFFS].view(FRAME_DTYPE).reshape(-1)
    return rec["time_us"].astype(np.int64) * 1000, rec["counter"].astype(np.int64)


def measure_stream(stream: SerialBatch | np.ndarray | None, *, source: str) -> ImuRate | None:
    """The measured rate of an IMU stream: a serial batch of ICD frames, or samples with a
    ``t_ns`` field (or the times themselves); None when it holds fewer than two frames.

    Raises
    ------
    ConfigError
        Naming ``source``, the bench time and both intervals, when the rate changes
        mid-stream (module docstring).
    """
    if stream is None:
        return None
    counter = None
    if isinstance(stream, SerialBatch):
        t, counter = frame_times(stream)
    elif stream.dtype.names and "t_ns" in stream.dtype.names:
        t = np.asarray(stream["t_ns"], np.int64)
    else:
        t = np.asarray(stream, np.int64)
    gaps = np.diff(t).astype(np.float64)
    if counter is not None and len(counter) > 1:
        # frames lost on the wire skip counter values: a gap over k counts is k intervals
        # (a repeated counter, a duplicate frame, counts as one)
        gaps /= np.maximum((np.diff(counter) % 256), 1)
    keep = gaps > 0
    gaps, at = gaps[keep], t[1:][keep]
    if not len(gaps):
        return None
    first = np.median(gaps)
    rate = ImuRate(float(np.median(gaps[gaps <= 1.5 * first])), len(t), source)  # lost frames' gaps left out
    n = len(gaps) // BLOCK_GAPS
    if n >= 2:
        med = np.median(gaps[: n * BLOCK_GAPS].reshape(n, BLOCK_GAPS), axis=1)
        off = np.flatnonzero(np.abs(med / med[0] - 1.0) > CHANGE_TOLERANCE)
        if off.size:
            k = int(off[0])
            raise ConfigError(
                f"the IMU stream changes rate mid-log: {1e9 / med[0]:.6g} Hz (median interval "
                f"{med[0] / 1e6:.6g} ms) at the start, {1e9 / med[k]:.6g} Hz ({med[k] / 1e6:.6g} ms) from bench "
                f"time {at[k * BLOCK_GAPS] / 1e9:.6g} s on; an estimator measures its IMU interval once, while it "
                "aligns, so the bench replays one rate per stream: cut the log at the change "
                "(docs/run_engine.md, 'The IMU rate of a replay')",
                file=source,
            )
    return rate


def require_rate(measured: ImuRate | None, declared_hz: float | None, *, file: str | None,
                 key: str | None) -> None:
    """Refuse a stream whose measured rate is not the declared one (module docstring).

    ``file`` and ``key`` name where the declaration comes from (a case's scenario and
    ``imu.rate``, a recording's ``run_start``, the ``--imu-rate`` option). Nothing to check
    without a declaration or a measurable stream.

    Raises
    ------
    ConfigError
        Naming both rates, the stream and the declaration.
    """
    if measured is None or declared_hz is None:
        return
    declared_ns = 1e9 / float(declared_hz)
    if abs(measured.interval_ns / declared_ns - 1.0) > RATE_TOLERANCE:
        raise ConfigError(
            f"the IMU stream of {measured.source} runs at {measured.describe()}, the declared rate is "
            f"{float(declared_hz):g} Hz ({declared_ns / 1e6:.6g} ms): an estimator would align and navigate at "
            "the stream's rate and be judged by a case written for the other; replay a stream with the "
            f"declared rate or declare its own (tolerance {RATE_TOLERANCE:.0%})",
            file=file,
            key=key,
        )


def case_rate(case: Any) -> tuple[float | None, str, str]:
    """The IMU rate a test case declares, with the file and key that declare it: its
    ``[sensors] imu`` table merged over its scenario's ``[imu]`` as a synthetic run of the
    case takes them (200 Hz when neither says); for a case built on field logs, its
    ``[scenario] log`` table's ``imu_rate`` (None when not given: the log's own rate)."""
    log = getattr(case.scenario, "log", None)
    if log is not None:
        return log.get("imu_rate_hz"), case.file, "scenario.log.imu_rate"
    from bench.acceptance.runner import sensor_tables
    from bench.run.case_runner import _scenario
    from bench.run.source import imu_settings

    sc = _scenario(case)
    table = sensor_tables(case, sc.doc).get("imu")
    _, rate = imu_settings(table, file=case.file)
    over = case.sensors.get("imu")
    if over is not None and "rate" in over.params:
        return rate, case.file, "sensors.imu.rate"
    if "rate" in (sc.doc.get("imu") or {}):
        return rate, str(sc.path), "imu.rate"
    return rate, case.file, "sensors.imu.rate (not given: 200 Hz, the default of a synthetic run)"


def check_replay(provider: Any, option: str | None, case: Any = None) -> ImuRate | None:
    """Before a replay runs: the stream its provider measured (``provider.imu_rate``)
    against every rate declared for it: ``--imu-rate`` (``option``), the ``case``'s, and a
    bench recording's own (``run_start.imu_rate_hz``). Returns the measured rate.

    Raises
    ------
    ConfigError
        A declared rate out of 1..1000 Hz, or one the stream does not run at (both named).
    """
    measured: ImuRate | None = getattr(provider, "imu_rate", None)
    if option is not None:
        hz = bounded_quantity(option, "frequency", "Hz", "imu_rate", file=None, key="--imu-rate")
        if not 1.0 <= hz <= 1000.0:
            raise ConfigError(f"expected an IMU rate of 1..1000 Hz (ICD 3), found {hz:g} Hz", key="--imu-rate")
        require_rate(measured, hz, file=None, key="--imu-rate")
    if case is not None:
        hz, file, key = case_rate(case)
        require_rate(measured, hz, file=file, key=key)
    recorded = getattr(provider, "run_start", {}).get("imu_rate_hz")
    if recorded is not None:
        require_rate(measured, float(recorded), file=str(getattr(provider, "path", "")) or None,
                     key="run_start.imu_rate_hz")
    return measured
