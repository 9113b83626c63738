"""The in-process estimator interface: what a Python DUT implements.

An estimator sees exactly what an ICD DUT reads off its links, decoded: IMU frames from
the ``imu`` line, fix epochs from the ``gnss`` line, and the CAN messages of the bench
(BENCH_TIME, BENCH_EPOCH, BENCH_CMD, ODOMETER, DRIVER_INPUT, DOPPLER), all quantized as the
wire quantizes them and with the wire faults of the run applied. The bench calls
:meth:`Estimator.step` once per scheduler step with everything that arrived since the
previous step; the estimator returns its navigation epochs up to the step time. The same
estimator runs as an external process over real links through
:mod:`bench.dut.harness`, which makes it the reference for external DUTs.

Minimal example::

    class Still(Estimator):
        name = "still"

        def step(self, inputs):
            sol = np.zeros(len(inputs.imu), NAV_SOLUTION_DTYPE)
            sol["t_ns"] = inputs.imu["t_ns"]          # one epoch per IMU frame
            ...                                        # lat, lon, h, vel_n, attitude
            return EstimatorOutput(sol)

Register it under a name with :func:`register_estimator` or the entry-point group
``bench.estimators`` (name = estimator name, value = a factory taking no arguments); test
cases name it in ``[dut] name``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from importlib import import_module
from importlib.metadata import entry_points
from typing import Any

import numpy as np

from bench.errors import ConfigError
from bench.topics import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE

__all__ = [
    "CanView",
    "stack_outputs",
    "DutInputs",
    "EstimatorOutput",
    "Estimator",
    "register_estimator",
    "create_estimator",
    "known_estimators",
    "ENTRY_POINT_GROUP",
]

ENTRY_POINT_GROUP = "bench.estimators"


class CanView(Mapping[str, dict[str, np.ndarray]]):
    """Per CAN message the decoded columns of one step, sliced from a window on demand."""

    __slots__ = ("_cache", "_columns", "_hi", "_lo")

    def __init__(self, columns: Mapping[str, Mapping[str, np.ndarray]], lo: Mapping[str, int], hi: Mapping[str, int]):
        self._columns = columns
        self._lo = lo
        self._hi = hi
        self._cache: dict[str, dict[str, np.ndarray]] = {}

    def __getitem__(self, name: str) -> dict[str, np.ndarray]:
        if name not in self._cache:
            cols = self._columns[name]
            a, b = self._lo[name], self._hi[name]
            self._cache[name] = {k: v[a:b] for k, v in cols.items()}
        return self._cache[name]

    def __iter__(self) -> Iterator[str]:
        return (k for k in self._columns if self._hi[k] > self._lo[k])

    def __len__(self) -> int:
        return sum(1 for _ in self)

    def count(self, name: str) -> int:
        """Frames of message ``name`` in this step."""
        return int(self._hi[name] - self._lo[name]) if name in self._columns else 0

    def total(self) -> int:
        """Frames of every message in this step."""
        hi = self._hi
        return sum(hi[k] - a for k, a in self._lo.items())


@dataclass
class DutInputs:
    """Decoded traffic that arrived in ``(previous step, t_ns]``.

    Every sample's ``rx_ns`` is the step time ``t_ns`` it is handed over at (a DUT knows
    bench time from BENCH_TIME only), in process and through the harness alike.

    Attributes
    ----------
    t_ns:
        Bench time of this step (the BENCH_TIME the DUT handles), ns.
    imu:
        IMU frames, :data:`bench.wire.imu.IMU_SAMPLE_DTYPE` (``t_ns`` end of interval,
        ``dtheta`` rad, ``dvel`` m/s, ``status``, ``temperature`` degC, ``counter``,
        ``rx_ns`` arrival).
    gnss:
        Completed fix epochs, :data:`bench.wire.nmea.GNSS_FIX_DTYPE` (``t_ns`` bench time of
        the measurement, ``lat``/``lon`` rad, ``h``, ``vel_n``, sigmas, ``quality``...).
    can:
        Per CAN message name the decoded columns (SI), each with ``rx_ns``.
    epoch_utc_ns:
        UTC of bench time zero once a BENCH_EPOCH has arrived, else None.
    """

    t_ns: int
    imu: np.ndarray
    gnss: np.ndarray
    can: Mapping[str, dict[str, np.ndarray]] = field(default_factory=dict)
    epoch_utc_ns: int | None = None

    def message(self, name: str) -> dict[str, np.ndarray]:
        """Columns of one CAN message (empty arrays when none arrived)."""
        if name in self.can and len(self.can[name].get("rx_ns", ())):
            return self.can[name]
        return {"rx_ns": np.zeros(0, np.int64)}

    def count(self) -> int:
        """Frames, fix epochs and CAN messages in this step."""
        n = len(self.imu) + len(self.gnss)
        if isinstance(self.can, CanView):
            return n + self.can.total()
        return n + sum(len(v.get("rx_ns", ())) for v in self.can.values())

    @property
    def odometer(self) -> dict[str, np.ndarray]:
        """ODOMETER: ``pulse_count`` (rolling uint16), ``speed`` m/s, ``reverse``, ``valid``."""
        return self.message("ODOMETER")

    @property
    def doppler(self) -> dict[str, np.ndarray]:
        """DOPPLER: ``speed`` m/s, ``quality``, ``valid``, ``low_signal``."""
        return self.message("DOPPLER")

    @property
    def driver(self) -> dict[str, np.ndarray]:
        """DRIVER_INPUT: ``left_lever``, ``right_lever``, ``steering`` rad, ``brake``."""
        return self.message("DRIVER_INPUT")

    @property
    def commands(self) -> np.ndarray:
        """BENCH_CMD codes (1 grid frame, 2 geographic frame, 3 reset filter) in arrival order."""
        return self.message("BENCH_CMD").get("command", np.zeros(0, np.int64))


@dataclass
class EstimatorOutput:
    """Navigation epochs of one step: NAV_SOLUTION records and, for the same epochs,
    NAV_QUALITY records (optional). ``rx_ns`` is filled by the bench."""

    solutions: np.ndarray = field(default_factory=lambda: np.zeros(0, NAV_SOLUTION_DTYPE))
    qualities: np.ndarray = field(default_factory=lambda: np.zeros(0, NAV_QUALITY_DTYPE))


class Estimator(ABC):
    """A navigation estimator under test, run inside the bench's process."""

    #: Registered name.
    name: str = ""

    def configure(self, config: Mapping[str, Any]) -> None:  # noqa: B027 - optional hook
        """Receive the DUT configuration of the test case (``[dut] config``: lever arms,
        pulse equivalent, initial position... whatever the estimator documents)."""

    @abstractmethod
    def step(self, inputs: DutInputs) -> EstimatorOutput:
        """Process the inputs of one step; return the epochs with time of validity up to
        ``inputs.t_ns`` not returned before."""

    def close(self) -> None:  # noqa: B027 - optional hook
        """End of the run."""


_FACTORIES: dict[str, Callable[[], Estimator]] = {}
_BUILTIN = {
    "decode_only": "bench.estimators.basic:DecodeOnly",
    "dead_reckoning": "bench.estimators.basic:DeadReckoning",
    "seed000": "bench.estimators.seed000:Seed000",
}


def register_estimator(name: str, factory: Callable[[], Estimator]) -> None:
    """Make ``factory()`` the estimator called ``name``."""
    _FACTORIES[name] = factory


def known_estimators() -> list[str]:
    """Names of the estimators this installation can create."""
    names = set(_FACTORIES) | set(_BUILTIN) | {ep.name for ep in entry_points(group=ENTRY_POINT_GROUP)}
    return sorted(names)


def create_estimator(name: str, config: Mapping[str, Any] | None = None) -> Estimator:
    """A configured estimator by name (registered, entry point, or built in)."""
    if name not in _FACTORIES:
        for ep in entry_points(group=ENTRY_POINT_GROUP):
            if ep.name == name:
                _FACTORIES[name] = ep.load()
                break
    if name not in _FACTORIES and name in _BUILTIN:
        mod, _, attr = _BUILTIN[name].partition(":")
        _FACTORIES[name] = getattr(import_module(mod), attr)
    if name not in _FACTORIES:
        raise ConfigError(f"no estimator {name!r}; known: {', '.join(known_estimators())}", key="dut.name")
    est = _FACTORIES[name]()
    est.configure(dict(config or {}))
    return est


def stack_outputs(parts: list[np.ndarray], rx: list[tuple[int, int]], dtype: np.dtype) -> np.ndarray | None:
    """The records of a window's steps in one array, ``rx_ns`` set to their step time."""
    if not parts:
        return None
    if all(part.dtype == dtype for part in parts):  # the usual case: the bytes joined (10x np.concatenate)
        out = np.frombuffer(b"".join([part.tobytes() for part in parts]), dtype).copy()
        times, counts = zip(*rx, strict=True)
        out["rx_ns"] = np.repeat(np.array(times, np.int64), np.array(counts))
        return out
    out = np.zeros(sum(n for _, n in rx), dtype)
    a = 0
    for part in parts:
        b = a + len(part)
        if part.dtype == dtype:
            out[a:b] = part  # same layout: a plain copy, no per-field promotion
        else:
            try:
                for name in dtype.names:
                    if part.dtype.names and name in part.dtype.names:
                        out[name][a:b] = part[name]
            except (TypeError, ValueError) as exc:
                raise ValueError(f"estimator output is not of the NAV record layout: {exc}") from exc
        a = b
    times, counts = zip(*rx, strict=True)
    out["rx_ns"] = np.repeat(np.array(times, np.int64), np.array(counts))
    return out
