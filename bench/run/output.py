"""The bench's side of the DUT's output: received frames decoded, checked and recorded.

Every frame from the DUT is recorded raw (``/wire/can/rx``), decoded with the checks of
:class:`~bench.wire.receive.NavReceiver` into ``/dut/nav_solution`` and
``/dut/nav_quality``, DUT_READY times go to ``/dut/ready``, every bad frame to
``/dut/bad_frames`` (never fatal). The DUT's standard output and error go to ``/dut/log``.
The Foxglove views of all this (map, pose, plots, ``foxglove.Log``) are derived from the
recording when the run is finished (:mod:`bench.scoring.viewwrite`).
"""

from __future__ import annotations

import numpy as np

from bench.dut.process import LogLine
from bench.frames import CanBatch
from bench.record.mcap_io import RecordingWriter
from bench.record.wire_topics import CAN_RX, write_can
from bench.topics import NAV_QUALITY_TOPIC, NAV_SOLUTION_TOPIC, TopicSpec
from bench.wire.receive import NavReceiver
from bench.wire.tally import Tally

__all__ = ["DutOutputRecorder", "READY_TOPIC", "BAD_FRAMES_TOPIC", "LOG_TOPIC"]

READY_TOPIC = TopicSpec(
    "/dut/ready",
    "bench.DutReady",
    np.dtype([("t_ns", "<i8"), ("rx_ns", "<i8")]),
    "DUT_READY: bench time up to which the DUT has processed its input, and its arrival",
    {"t_ns": "ns", "rx_ns": "ns"},
)
BAD_FRAMES_TOPIC = "/dut/bad_frames"
LOG_TOPIC = "/dut/log"


class DutOutputRecorder:
    """Decodes and records what the DUT sends (see the module docstring).

    Parameters
    ----------
    rec:
        The run's recording (wire topics already declared).
    """

    def __init__(self, rec: RecordingWriter):
        self.rec = rec
        self.tally = Tally()
        self.receiver = NavReceiver(tally=self.tally)
        #: When True, :meth:`feed` only keeps the frames; :meth:`process` decodes and records
        #: them later (real-time runs keep recording work out of the emission loop).
        self.deferred = False
        self._pending: list[CanBatch] = []
        self.solutions = 0
        self.qualities = 0
        self.last_ready_ns = -1
        for spec in (NAV_SOLUTION_TOPIC, NAV_QUALITY_TOPIC, READY_TOPIC):
            rec.columnar_topic(spec.topic, spec.schema, spec.dtype, description=spec.description, units=spec.units)
        rec.json_topic(
            BAD_FRAMES_TOPIC,
            "bench.BadFrame",
            {
                "type": "object",
                "properties": {
                    "t_ns": {"type": "integer"},
                    "link": {"type": "string"},
                    "kind": {"type": "string"},
                    "detail": {"type": "string"},
                    "data": {"type": "string", "description": "hex"},
                },
            },
        )
        rec.json_topic(
            LOG_TOPIC,
            "bench.DutLog",
            {
                "type": "object",
                "properties": {"t_ns": {"type": "integer"}, "stream": {"type": "string"}, "text": {"type": "string"}},
            },
        )

    def feed(self, frames: CanBatch) -> None:
        """Record and decode a batch of received frames (``t_ns`` = arrival, bench time)."""
        if len(frames) == 0:
            return
        if self.deferred:
            self._pending.append(frames)
            return
        self._record(frames)

    def process(self, max_batches: int | None = None) -> None:
        """Decode and record deferred frames (all, or the first ``max_batches`` batches).

        With no ``max_batches`` this is the end of the DUT's output: the qualities still
        waiting for their solutions are counted unpaired
        (:meth:`~bench.wire.receive.NavReceiver.finish`)."""
        n = len(self._pending) if max_batches is None else min(max_batches, len(self._pending))
        if n:
            batch, self._pending = self._pending[:n], self._pending[n:]
            self._record(CanBatch.concat(batch))
        if max_batches is None:
            self.receiver.finish()
            self.write_bad()

    def _record(self, frames: CanBatch) -> None:
        write_can(self.rec, CAN_RX, frames)
        out = self.receiver.feed(frames)
        if len(out.solutions):
            self.rec.write_block(NAV_SOLUTION_TOPIC.topic, out.solutions)
            self.solutions += len(out.solutions)
        if len(out.qualities):
            self.rec.write_block(NAV_QUALITY_TOPIC.topic, out.qualities)
            self.qualities += len(out.qualities)
        if len(out.ready_ns):
            r = np.zeros(len(out.ready_ns), READY_TOPIC.dtype)
            r["t_ns"], r["rx_ns"] = out.ready_ns, out.ready_rx_ns
            self.rec.write_block(READY_TOPIC.topic, r)
            self.last_ready_ns = max(self.last_ready_ns, int(out.ready_ns.max()))
        self.write_bad()

    def write_bad(self) -> None:
        """Record the bad frames kept since the last call."""
        for b in self.tally.pop_bad():
            self.rec.write_json(
                BAD_FRAMES_TOPIC,
                b.t_ns,
                {"t_ns": b.t_ns, "link": b.stream, "kind": b.kind, "detail": b.reason, "data": b.data.hex()},
            )

    def log(self, lines: list[LogLine], t_ns: int) -> None:
        """Record output lines of the DUT process at bench time ``t_ns``."""
        for ln in lines:
            self.rec.write_json(LOG_TOPIC, t_ns, {"t_ns": t_ns, "stream": ln.stream, "text": ln.text})
