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

The bench fills ``rx_ns`` and the epoch counters of what it returns (whatever the
estimator put there is overwritten: :mod:`bench.dut.epochs`); an epoch whose time of
validity is later than the step time, or an exception, ends the run as a DUT error.

Test cases name an estimator in ``[dut] name``: a name registered with
:func:`register_estimator` or in the entry-point group ``bench.estimators`` (name =
estimator name, value = a factory taking no arguments), or ``package.module:Class`` (an
:class:`Estimator` subclass or a factory returning one), imported from beside the test
case file first, then from the Python path. docs/estimators.md, "Writing your own
estimator".
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import import_module
from importlib.metadata import entry_points
from pathlib import Path
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
    """Per CAN message the decoded columns of one step, sliced from a window on demand.

    ``CanView(columns, lo, hi)``: message ``n``'s frames ``[lo[n], hi[n])`` of ``columns``;
    :meth:`at_step` makes the view of step ``k`` from the window's cut lists without
    building a dict per step (the bench's hot path: one view per 10 ms step)."""

    __slots__ = ("_cache", "_columns", "_cuts", "_k")

    def __init__(self, columns: Mapping[str, Mapping[str, np.ndarray]], lo: Mapping[str, int], hi: Mapping[str, int]):
        self._columns = columns
        self._cuts: Mapping[str, Sequence[int]] = {n: (lo[n], hi[n]) for n in lo}
        self._k = 0
        self._cache: dict[str, dict[str, np.ndarray]] = {}

    @classmethod
    def at_step(
        cls, columns: Mapping[str, Mapping[str, np.ndarray]], cuts: Mapping[str, Sequence[int]], k: int
    ) -> CanView:
        """The view of step ``k`` of a window: message ``n``'s frames
        ``[cuts[n][k], cuts[n][k + 1])`` of ``columns`` (``cuts`` shared by the steps)."""
        view = cls.__new__(cls)
        view._columns = columns
        view._cuts = cuts
        view._k = k
        view._cache = {}
        return view

    def __getitem__(self, name: str) -> dict[str, np.ndarray]:
        got = self._cache.get(name)
        if got is None:
            cols = self._columns[name]
            c, k = self._cuts[name], self._k
            a, b = c[k], c[k + 1]
            got = self._cache[name] = {key: v[a:b] for key, v in cols.items()}
        return got

    def columns(self, name: str, keys: Sequence[str]) -> list[np.ndarray] | None:
        """The columns ``keys`` of ``name`` in this step (zero-length if none arrived in this
        step but some in the window; None for a message not in the window): ``self[name][key]``
        for each key, without building the message's dict (a step's hot path)."""
        cols = self._columns.get(name)
        if cols is None:
            return None
        got = self._cache.get(name)
        if got is not None:
            return [got[key] for key in keys]
        c, k = self._cuts[name], self._k
        a, b = c[k], c[k + 1]
        return [cols[key][a:b] for key in keys]

    def get(self, name: str, default: Any = None) -> Any:  # type: ignore[override]
        """The columns of ``name`` (zero-length if none arrived in this step but some in the
        window), ``default`` for a message not in the window."""
        return self[name] if name in self._columns else default

    def __iter__(self) -> Iterator[str]:
        k = self._k
        return (n for n in self._columns if self._cuts[n][k + 1] > self._cuts[n][k])

    def __len__(self) -> int:
        return sum(1 for _ in self)

    def count(self, name: str) -> int:
        """Frames of message ``name`` in this step."""
        if name not in self._columns:
            return 0
        c, k = self._cuts[name], self._k
        return int(c[k + 1] - c[k])

    def total(self) -> int:
        """Frames of every message in this step."""
        k = self._k
        return sum(c[k + 1] - c[k] for c in self._cuts.values())


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
        """Columns of one CAN message of the bench: every field of it, zero-length arrays of
        the decoder's dtype when none arrived in this step (KeyError for a name that is not
        a bench message)."""
        cols = self.can.get(name)
        if cols is not None:
            return cols
        from bench.wire.receive import empty_columns  # the decoder's own columns (cantools: only when needed)

        return empty_columns(name)

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
        """BENCH_CMD codes in arrival order: :data:`~bench.wire.icd.CMD_SWITCH_TO_GRID`,
        :data:`~bench.wire.icd.CMD_SWITCH_TO_GEOGRAPHIC`, :data:`~bench.wire.icd.CMD_RESET_FILTER`."""
        return self.message("BENCH_CMD")["command"]


@dataclass
class EstimatorOutput:
    """Navigation epochs of one step: NAV_SOLUTION records and, for the same epochs,
    NAV_QUALITY records (optional), each with time of validity ``t_ns`` up to the step time.
    ``rx_ns`` and ``epoch`` are filled by the bench (:mod:`bench.dut.epochs`)."""

    solutions: np.ndarray = field(default_factory=lambda: np.zeros(0, NAV_SOLUTION_DTYPE))
    qualities: np.ndarray = field(default_factory=lambda: np.zeros(0, NAV_QUALITY_DTYPE))

    def __post_init__(self) -> None:
        sol, qual = self.solutions, self.qualities
        if type(sol) is np.ndarray and type(qual) is np.ndarray and sol.ndim == 1 and qual.ndim == 1 \
                and sol.dtype.names is not None and qual.dtype.names is not None:
            return  # the usual case, checked at once (one EstimatorOutput per step)
        for what, value, kind in (("solutions", self.solutions, "NAV_SOLUTION"),
                                  ("qualities", self.qualities, "NAV_QUALITY")):
            if not isinstance(value, np.ndarray) or value.dtype.names is None or value.ndim != 1:
                found = f"an array of {value.dtype}, shape {value.shape}" if isinstance(value, np.ndarray) \
                    else f"a {type(value).__name__}"
                raise TypeError(f"EstimatorOutput.{what}: expected a 1-D array of {kind} records, found {found}")


class Estimator(ABC):
    """A navigation estimator under test, run inside the bench's process."""

    #: Registered name.
    name: str = ""

    def configure(self, config: Mapping[str, Any]) -> None:  # noqa: B027 - optional hook
        """Receive the DUT configuration of the test case (``[dut] config``: lever arms,
        pulse equivalent, initial position... whatever the estimator documents)."""

    def warm_up(self) -> None:  # noqa: B027 - optional hook
        """Prepare what the first steps would otherwise prepare (compile numba kernels, load
        tables), once, after :meth:`configure` and before the first step: the bench calls it
        before the run starts and the harness before it answers its first BENCH_TIME, so a
        first step does not stall the run (through the harness, a kernel compiled inside a
        step leaves the bench without DUT_READY for as long as the compilation takes)."""

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
    "seed001": "bench.estimators.seed001:Seed001",
    "seed002": "bench.estimators.seed002:Seed002",
    "seed003": "bench.estimators.seed003:Seed003",
}


def register_estimator(name: str, factory: Callable[[], Estimator]) -> None:
    """Make ``factory()`` the estimator called ``name``."""
    _FACTORIES[name] = factory


def known_estimators() -> list[str]:
    """Names of the estimators this installation can create."""
    names = set(_FACTORIES) | set(_BUILTIN) | {ep.name for ep in entry_points(group=ENTRY_POINT_GROUP)}
    return sorted(names)


def create_estimator(
    name: str, config: Mapping[str, Any] | None = None, *, search: Sequence[str | Path | None] = ()
) -> Estimator:
    """A configured estimator by name: registered, entry point, built in, or
    ``package.module:Class`` (the module looked for in the folders ``search`` first, then on
    the Python path).

    Raises
    ------
    ConfigError
        (key ``dut.name``) No such estimator: an unknown name, a module or attribute that is
        not there, or something that is not an :class:`Estimator` subclass or factory.
    """
    if ":" in name:
        from bench.dut.loading import from_module

        factory = from_module(name, [Path(d) for d in search if d is not None])
    else:
        factory = _registered(name)
    est = factory()
    if not isinstance(est, Estimator):
        raise ConfigError(
            f"the estimator {name!r} made a {type(est).__module__}.{type(est).__qualname__}, not a "
            "bench.dut.Estimator",
            key="dut.name",
        )
    if not est.name:
        est.name = name
    est.configure(dict(config or {}))
    return est


def _registered(name: str) -> Callable[[], Estimator]:
    if name not in _FACTORIES:
        for ep in entry_points(group=ENTRY_POINT_GROUP):
            if ep.name == name:
                _FACTORIES[name] = ep.load()
                break
    if name not in _FACTORIES and name in _BUILTIN:
        mod, _, attr = _BUILTIN[name].partition(":")
        _FACTORIES[name] = getattr(import_module(mod), attr)
    if name not in _FACTORIES:
        raise ConfigError(
            f"no estimator {name!r}; known: {', '.join(known_estimators())}, or package.module:Class",
            key="dut.name",
        )
    return _FACTORIES[name]


def stack_step_outputs(
    sols: list[np.ndarray], s_rx: list[tuple[int, int]], quals: list[np.ndarray], q_rx: list[tuple[int, int]]
) -> tuple[np.ndarray | None, np.ndarray | None, int | None, str]:
    """The steps' NAV_SOLUTION and NAV_QUALITY records stacked (:func:`stack_outputs`).
    When a step's records are of another layout: those of the steps before it, the bench
    time of the first refused step and why; else ``(sol, qual, None, "")``."""
    try:
        return stack_outputs(sols, s_rx, NAV_SOLUTION_DTYPE), stack_outputs(quals, q_rx, NAV_QUALITY_DTYPE), None, ""
    except ValueError as exc:
        refused = (first_refused(sols, s_rx, NAV_SOLUTION_DTYPE), first_refused(quals, q_rx, NAV_QUALITY_DTYPE))
        bad = min(t for t in refused if t is not None)
        ks = [k for k, (t, _) in enumerate(s_rx) if t < bad]
        kq = [k for k, (t, _) in enumerate(q_rx) if t < bad]
        sol = stack_outputs([sols[k] for k in ks], [s_rx[k] for k in ks], NAV_SOLUTION_DTYPE)
        qual = stack_outputs([quals[k] for k in kq], [q_rx[k] for k in kq], NAV_QUALITY_DTYPE)
        return sol, qual, bad, str(exc)


def first_refused(parts: list[np.ndarray], rx: list[tuple[int, int]], dtype: np.dtype) -> int | None:
    """The step time of the first part :func:`stack_outputs` refuses (None: none is)."""
    for part, (t, n) in zip(parts, rx, strict=True):
        try:
            stack_outputs([part], [(t, n)], dtype)
        except ValueError:
            return t
    return None


def stack_outputs(parts: list[np.ndarray], rx: list[tuple[int, int]], dtype: np.dtype) -> np.ndarray | None:
    """The records of a window's steps in one array, ``rx_ns`` set to their step time."""
    if not parts:
        return None
    if all(isinstance(part, np.ndarray) and part.dtype == dtype for part in parts):  # usual: the bytes joined
        out = np.frombuffer(b"".join([part.tobytes() for part in parts]), dtype).copy()
        times, counts = zip(*rx, strict=True)
        out["rx_ns"] = np.repeat(np.array(times, np.int64), np.array(counts))
        return out
    out = np.zeros(sum(n for _, n in rx), dtype)
    a = 0
    for part in parts:
        if not isinstance(part, np.ndarray) or part.dtype.names is None:
            raise ValueError(f"estimator output is not of the NAV record layout: expected records, found {part!r:.80}")
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
