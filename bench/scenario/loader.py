"""Scenario files: a motion script (``[[segment]]``) or a recorded track (``[track]``).

``load_scenario("S000")`` finds ``test_cases/scenarios/S000*.toml``; a path is read as is
(a regular file of at most 64 MiB, :mod:`bench.config.files`). Loading checks what can be
checked without building the motion: the tables and keys, and that a motion script stays
bounded (``repeat`` counts, at most 100,000 segments after repeats, declared durations
within 30 days), so a runaway script is refused before any synthesis.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.config import files
from bench.config.bounds import bounded_quantity, check
from bench.config.table import check_keys
from bench.errors import ConfigError
from bench.paths import test_cases_dir
from bench.scenario.motion import GNSS_FLAGS, SURFACES, build_profile
from bench.scenario.script_values import check_script_size
from bench.scenario.trajectory import SegmentInfo, Trajectory
from bench.units import quantity

__all__ = ["Scenario", "load_scenario", "find_scenario", "read_toml", "check_script_size", "track_fit"]

_TOP_KEYS = {
    "scenario",
    "initial",
    "limits",
    "defaults",
    "segment",
    "track",
    "truth",
    # default sensor suite of the scenario (test cases may override)
    "imu",
    "doppler",
    "odometer",
    "bds",
    "driver",
    # sensor-level fault windows of the scenario (bench.faults.schedule)
    "fault",
    # motion from a vehicle FMU driven by a command timeline (bench.plant.scenario)
    "plant",
    "command",
}
_SCENARIO_KEYS = {"id", "title", "reference", "description", "start_utc", "assumed", "notes"}


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file (:func:`bench.config.files.read_toml`); errors name the file."""
    return files.read_toml(path)


@dataclass
class Scenario:
    """A scenario file, parsed and checked; :meth:`trajectory` builds its motion."""

    id: str
    title: str
    path: Path
    doc: dict[str, Any]
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def internal_rate_hz(self) -> float:
        """Rate of the truth's internal integration grid (``[truth] internal_rate``)."""
        value = self.doc.get("truth", {}).get("internal_rate", 1000.0)
        rate = bounded_quantity(value, "frequency", "Hz", "rate", file=str(self.path), key="truth.internal_rate")
        if rate < 1000.0:
            raise ConfigError(
                f"expected at least 1000 Hz, found {value!r}", file=str(self.path), key="truth.internal_rate"
            )
        return rate

    def trajectory(self) -> Trajectory:
        """Build the truth trajectory (may take a moment for long drives)."""
        if "track" in self.doc:
            return _track_trajectory(self)
        if "plant" in self.doc:
            from bench.plant.scenario import plant_trajectory  # the plant layer, only when asked for

            return plant_trajectory(self.doc, file=str(self.path), base=self.path.parent)
        return build_profile(self.doc, file=str(self.path), internal_rate_hz=self.internal_rate_hz)

    def text(self) -> str:
        """The file as written (to attach to recordings)."""
        return files.read_text(self.path, what="scenario file")


def find_scenario(name: str) -> Path:
    """Path of a scenario given as a path or as an id found in ``test_cases/scenarios/``."""
    p = Path(name)
    if p.suffix == ".toml" or p.exists():
        if not p.exists():
            raise ConfigError("file not found", file=str(p))
        return p
    folder = test_cases_dir() / "scenarios"
    hits = sorted(folder.glob(f"{name}*.toml"))
    if len(hits) == 1:
        return hits[0]
    known = ", ".join(sorted(h.stem for h in folder.glob("*.toml"))) or "none"
    if not hits:
        raise ConfigError(f"no scenario {name!r} in {folder}; known: {known}")
    raise ConfigError(f"scenario {name!r} is ambiguous in {folder}: {', '.join(h.name for h in hits)}")


def load_scenario(ref: str | Path) -> Scenario:
    """Load and check a scenario file given by path or id."""
    path = find_scenario(str(ref))
    doc = files.read_toml(path, what="scenario file")
    check_keys(doc, _TOP_KEYS, file=str(path), noun="table")
    meta = doc.get("scenario", {})
    if not isinstance(meta, dict) or "id" not in meta:
        raise ConfigError("expected a [scenario] table with an 'id'", file=str(path), key="scenario.id")
    check_keys(meta, _SCENARIO_KEYS, file=str(path), key="scenario")
    if sum(k in doc for k in ("track", "segment", "plant")) != 1:
        raise ConfigError(
            "a scenario has exactly one of [[segment]] tables, a [track] table or a [plant] table",
            file=str(path),
            key="segment",
        )
    sc = Scenario(id=str(meta["id"]), title=str(meta.get("title", "")), path=path, doc=doc, meta=meta)
    if "segment" in doc:
        truth = doc.get("truth", {})
        if not isinstance(truth, Mapping):
            raise ConfigError("expected a [truth] table", file=str(path), key="truth")
        check_script_size(doc["segment"], file=str(path), rate_hz=sc.internal_rate_hz)
    return sc


def _track_trajectory(sc: Scenario) -> Trajectory:
    from bench.scenario.track import SampledTrajectory, read_track

    file = str(sc.path)
    t = sc.doc["track"]
    if not isinstance(t, Mapping):
        raise ConfigError("expected a [track] table", file=file, key="track")
    allowed = {"file", "format", "start", "end", *_TRACK_FIT}
    check_keys(t, allowed, file=file, key="track")
    if "file" not in t:
        raise ConfigError("missing field", file=file, key="track.file")
    src = Path(t["file"])
    if not src.is_absolute():
        src = (sc.path.parent / src).resolve()
    track = read_track(src, t.get("format", "csv"))
    start = bounded_quantity(t["start"], "time", "s", "time", file=file, key="track.start") if "start" in t else None
    end = bounded_quantity(t["end"], "time", "s", "time", file=file, key="track.end") if "end" in t else None
    track = track.cleaned().cropped(start, end)
    defaults = sc.doc.get("defaults", {})
    gnss = defaults.get("gnss", "open")
    surface = defaults.get("surface", "asphalt")
    if gnss not in GNSS_FLAGS:
        raise ConfigError(f"expected one of {GNSS_FLAGS}, found {gnss!r}", file=file, key="defaults.gnss")
    if surface not in SURFACES:
        raise ConfigError(f"expected one of {SURFACES}, found {surface!r}", file=file, key="defaults.surface")
    duration = float(track.t[-1] - track.t[0]) if len(track.t) else 0.0
    check("duration", duration, file=file, key="track.file", shown=f"{duration:g} s of track in {src}")
    return SampledTrajectory(
        track, **track_fit(t, file=file), segments=[SegmentInfo(0, "track", 0.0, duration, gnss=gnss, surface=surface)]
    )


#: The fit settings of a [track] table: (dimension, unit of a bare number) of each key.
_TRACK_FIT = {
    "smoothing": ("length", "m"),
    "attitude_smoothing": ("angle", "deg"),
    "min_speed": ("velocity", "m/s"),
    "huber": ("dimensionless", "1"),
    "reject": ("dimensionless", "1"),
    "stop_speed": ("velocity", "m/s"),
    "stop_time": ("time", "s"),
    "turn_radius": ("length", "m"),
}


def track_fit(table: Mapping[str, Any], *, file: str | None = None) -> dict[str, float]:
    """The fit settings of a ``[track]`` table (SI), :class:`~bench.scenario.track_fit.TrackFit`'s
    defaults where a key is absent; each finite and not negative."""
    from bench.scenario.track_fit import TrackFit

    out = TrackFit().kwargs()
    for key, (dim, unit) in _TRACK_FIT.items():
        if key in table:
            v = quantity(table[key], dim, unit, file=file, key=f"track.{key}")
            if v < 0.0:
                raise ConfigError(
                    f"expected a value of at least 0, found {table[key]!r}", file=file, key=f"track.{key}"
                )
            out[key] = v
    if out["stop_speed"] > 0.0 and out["stop_time"] <= 0.0:
        raise ConfigError("expected a positive time with stop_speed set", file=file, key="track.stop_time")
    return out
