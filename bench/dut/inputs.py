"""The DUT's side of the links: bench traffic decoded into :class:`DutInputs`.

Both the in-process adapter and the harness that runs an in-process estimator as an
external process (:mod:`bench.dut.harness`) read the bench's traffic with the same
decoders (IMU resynchronisation, NMEA framing and epochs, CAN checks by kind), so an
estimator sees the same inputs either way. Decoding is done on whole batches; the decoded
samples carry their arrival time (``rx_ns``) and are cut into scheduler steps by it.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from bench.dut.estimator import CanView, DutInputs
from bench.frames import CanBatch, SerialBatch
from bench.wire.imu import IMU_SAMPLE_DTYPE
from bench.wire.imu_stream import ImuStreamDecoder
from bench.wire.nmea import GNSS_FIX_DTYPE
from bench.wire.nmea_stream import NmeaStreamDecoder
from bench.wire.receive import BenchTrafficDecoder
from bench.wire.tally import Tally

__all__ = ["InputDecoder", "Decoded"]


@dataclass
class Decoded:
    """Decoded traffic of one batch, every sample with ``rx_ns``."""

    imu: np.ndarray = field(default_factory=lambda: np.zeros(0, IMU_SAMPLE_DTYPE))
    gnss: np.ndarray = field(default_factory=lambda: np.zeros(0, GNSS_FIX_DTYPE))
    can: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)

    def cuts(self, step_times: np.ndarray, start_ns: int) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """Indices cutting the samples into steps: step ``k`` holds ``[cut[k], cut[k+1])``
        of each stream, the samples that arrived in ``(T_k-1, T_k]`` (the first step from
        ``start_ns``, inclusive)."""
        bounds = np.concatenate([[start_ns - 1], step_times])
        return (
            np.searchsorted(self.imu["rx_ns"], bounds, side="right"),
            np.searchsorted(self.gnss["rx_ns"], bounds, side="right"),
            {k: np.searchsorted(v["rx_ns"], bounds, side="right") for k, v in self.can.items()},
        )


class InputDecoder:
    """Stateful decoders of the three links, with one tally of bad frames by kind.

    Parameters
    ----------
    epoch_utc_ns:
        UTC of bench time zero if known in advance (else taken from BENCH_EPOCH).
    """

    def __init__(self, epoch_utc_ns: int | None = None):
        self.tally = Tally()
        self.can = BenchTrafficDecoder(tally=self.tally)
        self.imu = ImuStreamDecoder(tally=self.tally)
        self.gnss = NmeaStreamDecoder(epoch_utc_ns=epoch_utc_ns, tally=self.tally)
        self.epoch_utc_ns = epoch_utc_ns

    def feed(
        self, can: CanBatch | None = None, imu: SerialBatch | None = None, gnss: SerialBatch | None = None
    ) -> Decoded:
        """Decode what arrived (``t_ns`` of frames and chunks = arrival, bench time)."""
        out = Decoded()
        if can is not None and len(can):
            out.can = self.can.feed(can)
            ep = out.can.get("BENCH_EPOCH")
            if ep is not None and len(ep["rx_ns"]) and self.epoch_utc_ns is None:
                self.epoch_utc_ns = int(ep["epoch_utc_ns"][-1])
                self.gnss.epoch_utc_ns = self.epoch_utc_ns
        if imu is not None and len(imu):
            out.imu = self.imu.feed_batch(imu)
        if gnss is not None and len(gnss):
            parts = [
                self.gnss.feed(gnss.buf[gnss.offsets[k] : gnss.offsets[k + 1]].tobytes(), int(gnss.t_ns[k]))
                for k in range(len(gnss))
            ]
            parts = [p for p in parts if len(p)]
            if parts:
                out.gnss = np.concatenate(parts)
        return out

    def step_inputs(self, decoded: Decoded, step_times: np.ndarray, start_ns: int) -> Iterator[DutInputs]:
        """The :class:`DutInputs` of each step of a decoded window."""
        ci, cg, cc = decoded.cuts(step_times, start_ns)
        # what arrived within a step is handed over at the step: rx_ns is the step's time, as
        # for an external DUT, which learns bench time from BENCH_TIME only
        _stamp(decoded.imu, ci, step_times)
        _stamp(decoded.gnss, cg, step_times)
        for name, cols in decoded.can.items():
            _stamp(cols, cc[name], step_times)
        ci_l, cg_l = ci.tolist(), cg.tolist()
        cc_l = {k: v.tolist() for k, v in cc.items()}
        imu, gnss, can, epoch = decoded.imu, decoded.gnss, decoded.can, self.epoch_utc_ns
        at_step = CanView.at_step
        for k, t in enumerate(step_times.tolist()):
            yield DutInputs(t, imu[ci_l[k] : ci_l[k + 1]], gnss[cg_l[k] : cg_l[k + 1]], at_step(can, cc_l, k), epoch)


def _stamp(records, cuts: np.ndarray, step_times: np.ndarray) -> None:
    """Set ``rx_ns`` of the samples of each step ``[cuts[k], cuts[k+1])`` to its time."""
    rx = records["rx_ns"]
    rx[cuts[0] : cuts[-1]] = np.repeat(step_times, np.diff(cuts))
