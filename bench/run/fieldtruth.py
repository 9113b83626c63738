"""Truth for a replay of field logs: a ground-truth track of the drive written as ``/truth``.

Field logs carry no truth. When the drive was surveyed (a reference system on the
vehicle, the smartLoc ground truth, a post-processed RTK track), the track is read with
the readers of :mod:`bench.scenario.track` (smartLoc ``point3 t x y z`` or CSV), fitted
with a :class:`~bench.scenario.track.SampledTrajectory` (quintic splines: velocity,
attitude and rates are derivatives of one smooth curve; heading and pitch from the
direction of travel when the track has no attitude) and written as ``/truth`` records
at its rate (100 Hz by default) wherever it covers the replay, so that ``bench score``
judges the replay like any run.

Time: the track's own time column maps to bench time as ``bench = t + offset``
(``time = "bench"``: the track is in the replay's time, e.g. seconds since the drive's
start) or ``bench = t - epoch + offset`` (``time = "utc"``: the column is UTC seconds
since 1970 and ``epoch`` the UTC of bench time zero).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.errors import ConfigError
from bench.record.mcap_io import RecordingWriter
from bench.run.source import SEGMENTS_TOPIC, time_grid
from bench.scenario.records import TRUTH_TOPIC, truth_records
from bench.scenario.track import SampledTrajectory, Track, read_track
from bench.scenario.trajectory import truth_at

__all__ = ["TruthTrack", "TruthWriter", "TRUTH_TIMES"]

#: How a track's time column maps to bench time.
TRUTH_TIMES = ("bench", "utc")


@dataclass
class TruthTrack:
    """A truth track given with field logs.

    Attributes
    ----------
    path:
        The track file.
    format:
        ``smartloc`` or ``csv`` (see :mod:`bench.scenario.track`).
    time:
        ``bench`` or ``utc`` (see the module docstring).
    offset_ns:
        Added to the track's times, ns.
    smoothing:
        1-sigma position noise of the track, m (0: the spline passes through every sample;
        above 0 the fit rejects glitches and holds stops with the defaults of
        :class:`~bench.scenario.track_fit.TrackFit`, and :meth:`TruthWriter.describe`
        summarizes its report).
    rate_hz:
        Rate of the ``/truth`` records.
    samples:
        The track already read (a format read elsewhere, e.g. a KF-GINS ``truth.nav`` by
        :mod:`bench.exchange.field_logs`, its times in seconds as ``time`` says); None:
        read ``path`` as ``format``.
    """

    path: Path
    format: str = "smartloc"
    time: str = "bench"
    offset_ns: int = 0
    smoothing: float = 0.0
    rate_hz: float = 100.0
    samples: Track | None = None


class TruthWriter:
    """Writes a :class:`TruthTrack` as ``/truth`` window by window.

    Parameters
    ----------
    track:
        The track.
    epoch_ns:
        UTC of bench time zero (for ``time = "utc"``).
    duration_ns:
        Length of the replay; the track must overlap ``[0, duration]``.
    """

    def __init__(self, track: TruthTrack, epoch_ns: int, duration_ns: int):
        path = Path(track.path)
        if track.time not in TRUTH_TIMES:
            raise ConfigError(f"expected truth time 'bench' or 'utc', found {track.time!r}", key="truth_time")
        if not track.rate_hz > 0:
            raise ConfigError(f"expected a positive truth rate, found {track.rate_hz:g} Hz", key="truth_rate")
        if not path.is_file():
            raise ConfigError("truth track not found", file=str(path))
        self.track = track
        samples = (track.samples if track.samples is not None else read_track(path, track.format)).cleaned()
        base = -epoch_ns if track.time == "utc" else 0
        #: Bench time of the trajectory's time zero (the track's first sample), ns.
        self.zero_ns = round(float(samples.t[0]) * 1e9) + base + track.offset_ns
        self.end_ns = self.zero_ns + round(float(samples.t[-1] - samples.t[0]) * 1e9)
        if self.end_ns < 0 or self.zero_ns > duration_ns:  # checked before the (slower) fit
            raise ConfigError(
                f"the truth track covers bench time {self.zero_ns / 1e9:.3f} .. {self.end_ns / 1e9:.3f} s and the "
                f"replay 0 .. {duration_ns / 1e9:.3f} s: they do not overlap (set the truth offset or time base)",
                file=str(path),
            )
        self.traj = SampledTrajectory(samples, smoothing=track.smoothing)
        self.end_ns = self.zero_ns + self.traj.duration_ns
        self.epoch_ns = epoch_ns
        self.written = 0

    def describe(self) -> str:
        """One line for ``run_start``."""
        t = self.track
        rep = self.traj.fit_report
        fit = "" if t.smoothing <= 0.0 else (
            f" (residual RMS {rep.rms_m:.3f} m, {len(rep.rejected)} samples rejected, "
            f"{len(rep.stationary)} stops held)"
        )
        return (
            f"{t.path} ({t.format}), track time {'UTC' if t.time == 'utc' else 'as bench time'}"
            f"{f' + {t.offset_ns / 1e9:g} s' if t.offset_ns else ''}: bench {self.zero_ns / 1e9:.3f} .. "
            f"{self.end_ns / 1e9:.3f} s, {t.rate_hz:g} Hz, smoothing {t.smoothing:g} m{fit}"
        )

    def declare(self, rec: RecordingWriter) -> None:
        """Declare ``/truth`` and the track's segment (in bench time)."""
        s = TRUTH_TOPIC
        rec.columnar_topic(
            s.topic, s.schema, s.dtype, description=f"{s.description}; from {self.track.path}", units=s.units
        )
        rec.json_topic(SEGMENTS_TOPIC, "bench.Segments", {"type": "object"})
        z = self.zero_ns / 1e9
        rec.write_json(
            SEGMENTS_TOPIC,
            0,
            {
                "segments": [
                    {
                        "index": g.index,
                        "kind": g.kind,
                        "start_s": z + g.start_s,
                        "end_s": z + g.end_s,
                        "gnss": g.gnss,
                        "surface": g.surface,
                        "label": g.label or Path(self.track.path).name,
                    }
                    for g in self.traj.segments()
                ]
            },
        )

    def _covered(self, t: np.ndarray) -> np.ndarray:
        return t[(t >= self.zero_ns) & (t <= self.end_ns)]

    def write(self, rec: RecordingWriter, t0_ns: int, t1_ns: int, first: bool) -> None:
        """Write the truth of ``(t0, t1]`` (``[t0, t1]`` when ``first``) where the track covers it."""
        t = self._covered(time_grid(self.track.rate_hz, t0_ns, t1_ns, include_start=first))
        if len(t):
            tau = t - self.zero_ns
            records = truth_records(truth_at(self.traj, tau), self.traj.segment_at(tau * 1e-9))
            records["t_ns"] = t
            rec.write_block(TRUTH_TOPIC.topic, records)
            self.written += len(t)

    def counts(self) -> dict[str, int]:
        """Records written."""
        return {TRUTH_TOPIC.topic: self.written}
