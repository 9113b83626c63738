"""Fault schedules: time windows in which a sensor or a wire misbehaves on purpose.

A schedule is a list of TOML tables::

    [[fault]]
    start = "240 s"
    end = "245 s"
    target = "odometer"        # a sensor, or a link/message for wire faults
    kind = "idling"
    layer = "sensor"           # "sensor" (default) or "wire"
    params = { ... }           # kind-specific, quantities with units

Kinds are registered by the modules that implement them (:func:`register_kind`), with
the parameters they take, so a schedule is checked on load and errors name the file and
the key. Times and parameters are finite and bounded (:mod:`bench.config.bounds`: a
window within 30 days, a ``period`` parameter such as ``every`` 0 or at least 1 ms, and at
most 1,000,000 events per window). Every window is recorded (topic ``/faults``) so scoring
knows where they were.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from bench.config.bounds import bounded_quantity, check
from bench.config.table import check_keys
from bench.errors import ConfigError
from bench.units import quantity

__all__ = [
    "FaultWindow",
    "FaultSchedule",
    "ParamSpec",
    "register_kind",
    "registered_kinds",
    "parse_schedule",
    "FAULT_TOPIC",
    "FAULT_JSON_SCHEMA",
]

FAULT_TOPIC = "/faults"
LAYERS = ("sensor", "wire")


@dataclass(frozen=True)
class ParamSpec:
    """One parameter of a fault kind: dimension (see :data:`bench.units.DIMENSIONS`, or
    ``"text"``/``"integer"``/``"boolean"``), unit of bare numbers, default (None: required),
    and the :data:`bench.config.bounds.BOUNDS` kind bounding it (``bound``; time
    parameters default to ``offset``, within +-30 days). A ``period`` parameter repeats
    the fault; the window may hold at most the ``events`` bound of them."""

    dimension: str
    unit: str = ""
    default: Any = None
    description: str = ""
    bound: str | None = None


@dataclass(frozen=True)
class _Kind:
    layer: str
    targets: tuple[str, ...]
    kind: str
    params: dict[str, ParamSpec]
    description: str


#: (layer, kind, targets) -> kind; one kind name may be registered for several target
#: sets with different parameters (e.g. ``bias_step`` of the Doppler radar and of the IMU).
_REGISTRY: dict[tuple[str, str, tuple[str, ...]], _Kind] = {}


def register_kind(
    layer: str,
    targets: Iterable[str],
    kind: str,
    params: Mapping[str, ParamSpec] | None = None,
    description: str = "",
) -> None:
    """Declare a fault kind that ``targets`` accept on ``layer``.

    A target ``"*"`` accepts any target name (wire faults on any message or stream);
    a target ending in ``*`` matches by prefix (``"can:*"``). The same kind may be
    registered again for other targets; a window uses the registration its target matches.
    """
    if layer not in LAYERS:
        raise ValueError(f"layer must be one of {LAYERS}, found {layer!r}")
    _REGISTRY[(layer, kind, tuple(targets))] = _Kind(layer, tuple(targets), kind, dict(params or {}), description)


def registered_kinds() -> list[_Kind]:
    """Every registered kind (for documentation and error messages)."""
    return sorted(_REGISTRY.values(), key=lambda k: (k.layer, k.kind, k.targets))


def _target_ok(target: str, allowed: tuple[str, ...]) -> bool:
    return any(a == "*" or a == target or (a.endswith("*") and target.startswith(a[:-1])) for a in allowed)


@dataclass(frozen=True)
class FaultWindow:
    """One scheduled fault, times in integer ns of bench time, params in SI."""

    id: int
    layer: str
    target: str
    kind: str
    start_ns: int
    end_ns: int
    params: dict[str, Any] = field(default_factory=dict, compare=False, hash=False)
    #: Where the window was written: (file or None, key such as ``fault[2]``), for errors.
    origin: tuple[str | None, str] | None = field(default=None, compare=False, hash=False)

    def active(self, t_ns: int) -> bool:
        """Whether the window covers bench time ``t_ns`` (start inclusive, end exclusive)."""
        return self.start_ns <= t_ns < self.end_ns

    def to_json(self) -> dict[str, Any]:
        """The record written to the ``/faults`` topic."""
        return {
            "id": self.id,
            "layer": self.layer,
            "target": self.target,
            "kind": self.kind,
            "start_ns": self.start_ns,
            "end_ns": self.end_ns,
            "params": self.params,
        }

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> FaultWindow:
        """Inverse of :meth:`to_json`."""
        return cls(
            int(doc["id"]),
            str(doc["layer"]),
            str(doc["target"]),
            str(doc["kind"]),
            int(doc["start_ns"]),
            int(doc["end_ns"]),
            dict(doc.get("params", {})),
        )


FAULT_JSON_SCHEMA: dict[str, Any] = {
    "title": "bench.FaultWindow",
    "type": "object",
    "properties": {
        "id": {"type": "integer"},
        "layer": {"type": "string", "enum": list(LAYERS)},
        "target": {"type": "string"},
        "kind": {"type": "string"},
        "start_ns": {"type": "integer", "description": "bench time, ns"},
        "end_ns": {"type": "integer", "description": "bench time, ns (exclusive)"},
        "params": {"type": "object"},
    },
}


class FaultSchedule:
    """The windows of a run, queried by target and time."""

    def __init__(self, windows: Iterable[FaultWindow] = ()):
        self.windows = sorted(windows, key=lambda w: (w.start_ns, w.id))

    def __len__(self) -> int:
        return len(self.windows)

    def __iter__(self):
        return iter(self.windows)

    def for_target(self, target: str, layer: str | None = None) -> list[FaultWindow]:
        """Windows aimed at ``target`` (optionally on one layer)."""
        return [w for w in self.windows if w.target == target and (layer is None or w.layer == layer)]

    def active(self, target: str, t_ns: int) -> list[FaultWindow]:
        """Windows on ``target`` covering ``t_ns``."""
        return [w for w in self.windows if w.target == target and w.active(t_ns)]

    def overlapping(self, target: str, t0_ns: int, t1_ns: int) -> list[FaultWindow]:
        """Windows on ``target`` intersecting ``[t0_ns, t1_ns)``."""
        return [w for w in self.windows if w.target == target and w.start_ns < t1_ns and w.end_ns > t0_ns]


def _param(value: Any, spec: ParamSpec, file: str | None, key: str) -> Any:
    if spec.dimension == "text":
        if not isinstance(value, str):
            raise ConfigError(f"expected text, found {value!r}", file=file, key=key)
        return value
    if spec.dimension == "integer":
        if not isinstance(value, int) or isinstance(value, bool):
            raise ConfigError(f"expected an integer, found {value!r}", file=file, key=key)
        return value if spec.bound is None else check(spec.bound, value, file=file, key=key)
    if spec.dimension == "boolean":
        if not isinstance(value, bool):
            raise ConfigError(f"expected true or false, found {value!r}", file=file, key=key)
        return value
    kind = spec.bound or ("offset" if spec.dimension == "time" else None)
    if isinstance(value, list):
        return [_quantity(v, spec, kind, file, f"{key}[{i}]") for i, v in enumerate(value)]
    return _quantity(value, spec, kind, file, key)


def _quantity(value: Any, spec: ParamSpec, kind: str | None, file: str | None, key: str) -> float:
    if kind is None:
        return quantity(value, spec.dimension, spec.unit, file=file, key=key)
    return bounded_quantity(value, spec.dimension, spec.unit, kind, file=file, key=key)


def _check_events(params: Mapping[str, Any], spec: _Kind, start: float, end: float, file: str | None, k: str) -> None:
    """At most the ``events`` bound of repetitions of a periodic fault in its window."""
    for name, ps in spec.params.items():
        every = params.get(name)
        if ps.bound == "period" and isinstance(every, float) and every > 0.0:
            n = int((end - start) / every) + 1
            check("events", n, file=file, key=f"{k}.params.{name}",
                  shown=f"{n} (a {end - start:g} s window, every {every:g} s)")


def parse_schedule(tables: Any, *, file: str | None = None, key: str = "fault", first_id: int = 0) -> FaultSchedule:
    """Check and convert ``[[fault]]`` tables into a :class:`FaultSchedule`."""
    if tables is None:
        return FaultSchedule()
    if not isinstance(tables, list):
        raise ConfigError("expected a list of [[fault]] tables", file=file, key=key)
    windows: list[FaultWindow] = []
    allowed = {"start", "end", "duration", "target", "kind", "layer", "params", "label"}
    for i, t in enumerate(tables):
        k = f"{key}[{i}]"
        if not isinstance(t, Mapping):
            raise ConfigError("expected a table", file=file, key=k)
        check_keys(t, allowed, file=file, key=k)
        layer = t.get("layer", "sensor")
        if layer not in LAYERS:
            raise ConfigError(f"expected one of {', '.join(LAYERS)}, found {layer!r}", file=file, key=f"{k}.layer")
        kind = t.get("kind")
        candidates = [v for (ll, kk, _), v in _REGISTRY.items() if ll == layer and kk == str(kind)]
        if not candidates:
            known = ", ".join(sorted({kk for (ll, kk, _) in _REGISTRY if ll == layer})) or "none registered"
            raise ConfigError(f"unknown {layer} fault kind {kind!r}; known: {known}", file=file, key=f"{k}.kind")
        target = t.get("target")
        spec = next((c for c in candidates if isinstance(target, str) and _target_ok(target, c.targets)), None)
        if spec is None:
            allowed_targets = [a for c in candidates for a in c.targets]
            raise ConfigError(
                f"a {kind} fault applies to {', '.join(allowed_targets)}, found target {target!r}",
                file=file,
                key=f"{k}.target",
            )
        if "start" not in t:
            raise ConfigError("missing field", file=file, key=f"{k}.start")
        start = quantity(t["start"], "time", "s", file=file, key=f"{k}.start")
        if ("end" in t) == ("duration" in t):
            raise ConfigError("give exactly one of 'end' and 'duration'", file=file, key=f"{k}.end")
        end = (
            quantity(t["end"], "time", "s", file=file, key=f"{k}.end")
            if "end" in t
            else start + bounded_quantity(t["duration"], "time", "s", "duration", file=file, key=f"{k}.duration")
        )
        if start < 0.0 or end <= start:
            raise ConfigError(
                f"expected 0 <= start < end, found start {start:g} s, end {end:g} s", file=file, key=f"{k}.end"
            )
        check("time", start, file=file, key=f"{k}.start", shown=t["start"])
        check("time", end, file=file, key=f"{k}.end" if "end" in t else f"{k}.duration", shown=t.get("end", end))
        raw = t.get("params", {})
        if not isinstance(raw, Mapping):
            raise ConfigError("expected a table of parameters", file=file, key=f"{k}.params")
        params: dict[str, Any] = {}
        for name in raw:
            if name not in spec.params:
                known = ", ".join(sorted(spec.params)) or "none"
                raise ConfigError(
                    f"unknown parameter {name!r} of {kind}; expected: {known}", file=file, key=f"{k}.params.{name}"
                )
        for name, ps in spec.params.items():
            if name in raw:
                params[name] = _param(raw[name], ps, file, f"{k}.params.{name}")
            elif ps.default is None:
                raise ConfigError(f"missing parameter of {kind}", file=file, key=f"{k}.params.{name}")
            else:
                params[name] = ps.default
        _check_events(params, spec, start, end, file, k)
        windows.append(
            FaultWindow(first_id + i, layer, target, str(kind), round(start * 1e9), round(end * 1e9), params, (file, k))
        )
    return FaultSchedule(windows)
