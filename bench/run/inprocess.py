"""The in-process DUT adapter: the bench calls the estimator directly.

The bench's traffic of a window, already encoded and faulted as it would be on the
wire, is decoded by the DUT-side decoders (:mod:`bench.dut.inputs`); the estimator is
called once per scheduler step with what arrived up to that step; its epochs are encoded
into NAV_SOLUTION / NAV_QUALITY frames as the ICD puts them on the bus, stamped with the
step time and numbered (:mod:`bench.dut.epochs`), so the bench receives and records them
exactly as from an external DUT.

The estimator failing ends the run as a :class:`~bench.errors.DutError` (``dut_failed``,
FAIL) whose reason says how: it raised (its traceback written to the DUT's log as an
external DUT's stderr would be), did not return from a step within the step timeout
(``[clock] timeout``, as an external DUT's DUT_READY: :mod:`bench.run.watchdog` stops it),
flooded (more epochs in one step than an external DUT may send frames: ``[dut]
flood_frames_per_s`` times the step, at least 100), returned an epoch later than the step
time, returned records of another layout, or values no NAV frame can carry. A
``MemoryError`` is the one failure the bench cannot pin on the estimator, which shares its
process and memory: it ends the run ``dut_error`` (ERROR), saying so. The frames of the
steps before stay in :attr:`partial`; the earliest failure is the one reported.

What the estimator writes on standard output or error when it is closed at the end of
the run (a summary, diagnostics) goes to the DUT's log as an external DUT's lines do.
"""

from __future__ import annotations

import contextlib
import io
import time
import traceback
from collections.abc import Callable

import numpy as np

from bench.dut.epochs import EpochNumbering, first_late, late_message
from bench.dut.estimator import Estimator, EstimatorOutput, stack_step_outputs
from bench.dut.inputs import InputDecoder
from bench.dut.process import LogLine
from bench.errors import CodecError, DutError
from bench.frames import CanBatch
from bench.run.traffic import Traffic
from bench.run.watchdog import StepTimeout, StepWatchdog
from bench.wire.can import CanEncoder

__all__ = ["InProcessDut", "traceback_lines"]


def traceback_lines(exc: BaseException) -> list[LogLine]:
    """The traceback of ``exc`` as the stderr lines of a DUT's log."""
    try:
        text = "".join(traceback.format_exception(exc))
    except Exception:  # an exception whose __str__ fails: still say what it was
        text = f"{type(exc).__name__} (its traceback could not be formatted)"
    return [LogLine(0, "stderr", line) for line in text.rstrip("\n").split("\n")]


class InProcessDut:
    """Drives an :class:`~bench.dut.estimator.Estimator` step by step.

    Parameters
    ----------
    estimator:
        The configured estimator.
    epoch_utc_ns:
        UTC of bench time zero (the DUT learns it from BENCH_EPOCH anyway).
    on_lines:
        Where the estimator's traceback goes when it raises, ``(lines, bench time)`` (the
        run's ``/dut/log``).
    step_timeout_s:
        A step that has not returned after this long is stopped and ends the run (None: no
        watchdog).
    step_ns, flood_frames_per_s:
        The scheduler step and the frame rate beyond which a DUT floods: more epochs
        (solutions and qualities) in one step than ``flood_frames_per_s`` times the step
        (at least 100) end the run.
    """

    def __init__(
        self,
        estimator: Estimator,
        epoch_utc_ns: int | None = None,
        on_lines: Callable[[list[LogLine], int], None] | None = None,
        *,
        step_timeout_s: float | None = None,
        step_ns: int = 10_000_000,
        flood_frames_per_s: int = 20_000,
    ):
        self.estimator = estimator
        self.step_timeout_s = step_timeout_s
        self.flood = max(100, int(flood_frames_per_s * step_ns * 1e-9))
        self.watchdog = StepWatchdog(step_timeout_s).__enter__() if step_timeout_s is not None else None
        self.decoder = InputDecoder(epoch_utc_ns)
        self.encoder = CanEncoder(wire_range=True)  # as a DUT puts it on the bus
        self.numbering = EpochNumbering()
        self.on_lines = on_lines
        self.epochs = 0
        self.last_t_ns = 0
        #: The frames of the steps before the estimator failed in :meth:`exchange` (the
        #: engine records them before it ends the run).
        self.partial: CanBatch | None = None

    def exchange(self, traffic: Traffic, step_times: np.ndarray, start_ns: int) -> CanBatch:
        """Feed one window's traffic; return the DUT's frames (``t_ns`` = the step they
        were produced in)."""
        decoded = self.decoder.feed(traffic.can, traffic.imu, traffic.gnss)
        sols: list[np.ndarray] = []
        quals: list[np.ndarray] = []
        s_rx: list[tuple[int, int]] = []
        q_rx: list[tuple[int, int]] = []
        step = self.estimator.step
        dog = self.watchdog
        name = self.estimator.name
        for inputs in self.decoder.step_inputs(decoded, step_times, start_ns):
            self.last_t_ns = inputs.t_ns
            try:
                if dog is None:
                    out = step(inputs)
                else:
                    token = dog.arm()
                    try:
                        out = step(inputs)
                    finally:
                        dog.disarm(token)
            except StepTimeout as exc:  # it hangs: stopped by the watchdog
                self.partial = self._stacked(sols, s_rx, quals, q_rx)
                self._log_traceback(exc, inputs.t_ns)
                raise DutError(
                    f"the estimator {name!r} did not return from its step at bench time {inputs.t_ns / 1e9:.3f} s "
                    f"within the step timeout of {self.step_timeout_s:g} s (it hangs; [clock] timeout)"
                ) from None
            except SystemExit as exc:  # sys.exit() in the estimator: it ended itself, not the bench
                self.partial = self._stacked(sols, s_rx, quals, q_rx)
                self._log_traceback(exc, inputs.t_ns)
                raise DutError(
                    f"the estimator {name!r} called exit({exc.code!r}) at bench time {inputs.t_ns / 1e9:.3f} s"
                ) from None
            except MemoryError as exc:  # in the bench's own process: whose memory ran out cannot be told
                self.partial = self._stacked(sols, s_rx, quals, q_rx)
                self._log_traceback(exc, inputs.t_ns)
                raise DutError(
                    f"the estimator {name!r} raised MemoryError at bench time {inputs.t_ns / 1e9:.3f} s (it runs "
                    "in the bench's process, so the bench cannot tell whether the estimator or the bench used the "
                    "memory up; run it as an external DUT to tell)", certain=False
                ) from exc
            except Exception as exc:  # the estimator under test failed: that ends the run
                self.partial = self._stacked(sols, s_rx, quals, q_rx)  # an earlier failure is raised here
                self._log_traceback(exc, inputs.t_ns)
                raise DutError(
                    f"the estimator {name!r} raised at bench time {inputs.t_ns / 1e9:.3f} "
                    f"s: {type(exc).__name__}: {exc}"
                ) from exc
            if not isinstance(out, EstimatorOutput):
                self.partial = self._stacked(sols, s_rx, quals, q_rx)
                raise DutError(
                    f"the estimator {self.estimator.name!r} returned a {type(out).__name__} at bench time "
                    f"{inputs.t_ns / 1e9:.3f} s, not an EstimatorOutput"
                )
            n = len(out.solutions) + len(out.qualities)
            if n > self.flood:
                self.partial = self._stacked(sols, s_rx, quals, q_rx)
                raise DutError(
                    f"the estimator {name!r} floods: {n} epochs (solutions and qualities) in the step at bench time "
                    f"{inputs.t_ns / 1e9:.3f} s (limit {self.flood}, as an external DUT's frames)"
                )
            if len(out.solutions):
                sols.append(out.solutions)
                s_rx.append((inputs.t_ns, len(out.solutions)))
            if len(out.qualities):
                quals.append(out.qualities)
                q_rx.append((inputs.t_ns, len(out.qualities)))
        return self._stacked(sols, s_rx, quals, q_rx)

    def _stacked(
        self, sols: list[np.ndarray], s_rx: list[tuple[int, int]], quals: list[np.ndarray], q_rx: list[tuple[int, int]]
    ) -> CanBatch:
        sol, qual, bad, why = stack_step_outputs(sols, s_rx, quals, q_rx)
        if bad is not None:  # records of another layout: the steps before it were delivered
            self.partial = self._checked(sol, qual)  # (an earlier failure among them is raised here)
            raise DutError(f"the estimator {self.estimator.name!r} at bench time {bad / 1e9:.3f} s: {why}")
        return self._checked(sol, qual)

    def _checked(self, sol: np.ndarray | None, qual: np.ndarray | None) -> CanBatch:
        """Frames of the stacked records, numbered; an epoch later than its step ends here."""
        late = first_late(sol, qual)
        if late is not None:  # an epoch from the future: the steps before it were delivered
            step_ns = late[1]
            keep = [r[r["rx_ns"] < step_ns] if r is not None else None for r in (sol, qual)]
            self.numbering.number(*keep)
            # (values of the epochs before that no frame can carry: that earlier failure is raised)
            self.partial = self._frames(*(r if r is not None and len(r) else None for r in keep))
            raise DutError(late_message(self.estimator.name, *late))
        self.numbering.number(sol, qual)
        return self._frames(sol, qual)

    def _log_traceback(self, exc: BaseException, t_ns: int) -> None:
        """The estimator's traceback on the DUT's log, as an external DUT's stderr."""
        if self.on_lines is not None:
            self.on_lines(traceback_lines(exc), t_ns)

    def _frames(self, sols: np.ndarray | None, quals: np.ndarray | None) -> CanBatch:
        parts = []
        try:
            if sols is not None:
                parts.append(self.encoder.encode_records("NAV_SOLUTION", sols))
            if quals is not None:
                parts.append(self.encoder.encode_records("NAV_QUALITY", quals))
        except CodecError as exc:  # values no NAV frame can carry (NaN, too large): the DUT failed
            self.partial = self._before_failure(sols, quals)
            raise DutError(f"the estimator {self.estimator.name!r} output does not fit NAV frames: {exc}") from exc
        if sols is not None:
            self.epochs += len(sols)
        if not parts:
            return CanBatch.empty(64)
        batch = CanBatch.concat(parts)
        return batch.take(np.argsort(batch.t_ns, kind="stable"))

    def _before_failure(self, sols: np.ndarray | None, quals: np.ndarray | None) -> CanBatch | None:
        """The frames of the epochs before the first one that cannot be encoded (they
        were delivered; the recording keeps them)."""
        cut = None
        for name, recs in (("NAV_SOLUTION", sols), ("NAV_QUALITY", quals)):
            if recs is None:
                continue
            k = self._encodable_prefix(name, recs)
            if k < len(recs):
                t = int(recs["t_ns"][k])
                cut = t if cut is None else min(cut, t)
        if cut is None:
            return None
        keep = [r[r["t_ns"] < cut] if r is not None else None for r in (sols, quals)]
        try:
            return self._frames(*(r if r is not None and len(r) else None for r in keep))
        except DutError:
            return None

    def _encodable_prefix(self, name: str, recs: np.ndarray) -> int:
        """The largest k with ``recs[:k]`` encodable (bisection: a few encodes)."""
        lo, hi = 0, len(recs)
        while lo < hi:
            mid = (lo + hi + 1) // 2
            try:
                self.encoder.encode_records(name, recs[:mid])
                lo = mid
            except CodecError:
                hi = mid - 1
        return lo

    def close(self) -> None:
        """End of the run: the watchdog stopped, the estimator's ``close``, its output lines
        on the DUT's log."""
        if self.watchdog is not None:
            self.watchdog.close()
        out, err = io.StringIO(), io.StringIO()
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                self.estimator.close()
        finally:
            if self.on_lines is not None:
                now = time.monotonic_ns()
                lines = [LogLine(now, stream, text) for stream, buf in (("stdout", out), ("stderr", err))
                         for text in buf.getvalue().splitlines()]
                if lines:
                    self.on_lines(lines, self.last_t_ns)
