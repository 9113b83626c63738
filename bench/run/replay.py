"""Replay: an earlier run's traffic re-emitted into the links, or a field recording's.

:class:`RecordingReplay` takes a bench recording. Without a new fault schedule it
re-emits the recorded frames and bytes as they went out, frame for frame (BENCH_TIME
frames are rebuilt only when the clock mode changes the lockstep bit; of the source's
start-up one round is kept, and the counters after it continue from there). With a new
schedule it re-encodes the recorded sensor samples (after the original sensor faults,
which live in the samples) and applies the new wire faults instead of the old ones. The
recorded truth, samples, segments and fault windows are copied into the new recording,
so the replayed run is scored like the original.

A seek (``start_ns``) makes a run of its own that starts at the seek point: the DUT's
bench time is 0 there (:mod:`bench.run.rebase` moves the traffic, the samples, the
truth and the epoch), so a DUT aligns and is judged from the point it was started at.

The source is read as far as it goes; when it was never finished, is damaged, ended
early or is itself a replay of such a source, the replay says so in its ``run_start``
(:mod:`bench.record.provenance`) and scoring makes it ERROR unless the replay was run
with ``accept_damaged_source``; its length is then that of what the source holds.

:class:`LogReplay` (:mod:`bench.run.logreplay`) takes field logs: a python-can log
(ASC, BLF) with the sensor messages and byte logs of the IMU and GNSS lines.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bench.errors import ConfigError
from bench.faults.schedule import FAULT_JSON_SCHEMA, FAULT_TOPIC, FaultSchedule, FaultWindow
from bench.faults.wire import WIRE_EVENT_DTYPE
from bench.frames import CanBatch, SerialBatch
from bench.record.mcap_io import COLUMNAR, RecordingReader, RecordingWriter
from bench.record.provenance import source_metadata
from bench.record.wire_topics import CAN_TX, SERIAL_TX, read_can, read_serial
from bench.run.fieldcan import with_lockstep_bit
from bench.run.imu_rate import measure_stream
from bench.run.provider import COMMANDS_TOPIC, TrafficProvider
from bench.run.rebase import rebase_can, rebase_records, rebase_segments, rebase_serial, rebase_window
from bench.run.source import SEGMENTS_TOPIC
from bench.run.startup import drop_handshake_copies
from bench.run.traffic import Traffic, TrafficEncoder, _ordered, slice_window

__all__ = ["RecordingReplay"]

_SAMPLE_KINDS = ("imu", "doppler", "odometer", "bds", "driver")
_COPIED_JSON = (SEGMENTS_TOPIC, COMMANDS_TOPIC)


class RecordingReplay(TrafficProvider):
    """The traffic of a bench recording (see the module docstring).

    Parameters
    ----------
    path:
        The recording.
    lockstep:
        Clock mode of the replay (BENCH_TIME's lockstep bit).
    faults:
        A new fault schedule (wire layer only); None replays the frames as recorded.
    seed:
        Seed of the new wire faults (default: the original run's).
    start_ns:
        Seek: replay from this bench time of the source on (whole milliseconds; the
        engine's step must divide it); the replay's own bench time starts there at 0.
    accept_damaged_source:
        Judge the replay although its source cannot be trusted (recorded in ``run_start``).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        lockstep: bool,
        faults: FaultSchedule | None = None,
        seed: int | None = None,
        start_ns: int = 0,
        accept_damaged_source: bool = False,
    ):
        self.path = Path(path)
        self.seek_ns = int(start_ns)
        self.start_ns = 0  # the replay's own bench time starts at the seek point
        self.reader = RecordingReader(self.path)
        md = self.reader.metadata()
        start = md.get("run_start", {})
        if not start:
            raise ConfigError("no run_start metadata: not the recording of a bench run", file=str(self.path))
        self.run_start = start
        self.provenance = source_metadata(self.reader, accepted=accept_damaged_source)
        if self.seek_ns < 0 or self.seek_ns % 1_000_000:
            raise ConfigError(f"the start must be whole milliseconds from 0 on, found {self.seek_ns / 1e9:g} s",
                              key="--start")
        self.topics = self.reader.topics()
        if CAN_TX not in self.topics and faults is None:
            raise ConfigError(
                f"no {CAN_TX}: a synth recording has samples but no traffic; "
                "replay it with a fault schedule (even an empty one) to encode the samples",
                file=str(self.path),
            )
        self.epoch_ns = int(start.get("epoch_utc_ns", 0)) + self.seek_ns
        self.seed = int(seed if seed is not None else start.get("seed", 0))
        self.lockstep = lockstep
        self.faults = faults
        self._columns: dict[str, np.ndarray] = {}
        for name, info in self.topics.items():
            if (
                info.encoding == COLUMNAR
                and info.messages
                and not name.startswith(("/wire/", "/dut/", "/bench/", "/faults/wire"))
            ):
                self._columns[name] = rebase_records(self.reader.read_columnar(name), self.seek_ns)
        self._json = {t: self._rebased_json(t) for t in _COPIED_JSON if t in self.topics}
        self._schemas = {name: self.topics[name].schema for name in self._columns}
        original = (
            [FaultWindow.from_json(d) for _, d in self.reader.iter_json(FAULT_TOPIC)]
            if (FAULT_TOPIC in self.topics)
            else []
        )
        original = [w for w in (rebase_window(w, self.seek_ns) for w in original) if w is not None]
        if faults is None:
            self.windows = original
            self._traffic = self._recorded_traffic()
            self.encoder = None
        else:
            bad = [w for w in faults if w.layer != "wire"]
            if bad:
                raise ConfigError(
                    f"fault {bad[0].id} ({bad[0].kind} on {bad[0].target}) acts on a sensor; a replay "
                    "re-emits recorded samples and can only add wire faults",
                    key="fault",
                )
            keep = [w for w in original if w.layer != "wire"]
            first_id = max((w.id for w in keep), default=-1) + 1
            new = [
                FaultWindow(first_id + i, w.layer, w.target, w.kind, w.start_ns, w.end_ns, w.params, w.origin)
                for i, w in enumerate(faults)
            ]
            self.windows = keep + new
            sensor_topics = {k: f"/{k}" for k in _SAMPLE_KINDS if f"/{k}" in self._columns}
            commands = [(int(d["t_ns"]), int(d["code"])) for _, d in self._json.get(COMMANDS_TOPIC, [])]
            self.encoder = TrafficEncoder(
                [],
                epoch_ns=self.epoch_ns,
                lockstep=lockstep,
                schedule=FaultSchedule(new),
                seed=self.seed,
                commands=commands,
                topics=sensor_topics,
            )
            self._traffic = None
        self.imu_rate = measure_stream(self._traffic[1] if self._traffic is not None else self._columns.get("/imu"),
                                       source=str(self.path))  # refuses a rate change; bench.run.imu_rate
        span = [int(v["t_ns"].max()) for v in self._columns.values() if len(v)]
        if self._traffic is not None:
            span += [int(b.t_ns.max()) for b in self._traffic if len(b)]
        recorded = max(span) if span else 0
        total = round(float(start.get("duration_s", 0)) * 1e9)
        if total and self.seek_ns >= total:
            raise ConfigError(f"the start {self.seek_ns / 1e9:g} s lies past the end of the recording "
                              f"({total / 1e9:g} s)", key="--start")
        self.duration_ns = total - self.seek_ns if total else recorded
        if self.provenance["source_complete"] == "false":  # what the source holds, not what it planned
            self.duration_ns = min(self.duration_ns, recorded)
        if self.duration_ns <= 0:
            raise ConfigError(f"nothing to replay: the recording holds nothing from {self.seek_ns / 1e9:g} s on",
                              key="--start" if self.seek_ns else "recording")

    def _rebased_json(self, topic: str) -> list[tuple[int, Any]]:
        """(log time, document) of a copied JSON topic, moved to the replay's bench time."""
        out = []
        for t_log, doc in self.reader.iter_json(topic):
            if topic == SEGMENTS_TOPIC and isinstance(doc, dict):
                doc = rebase_segments(doc, self.seek_ns)
            elif topic == COMMANDS_TOPIC and isinstance(doc, dict) and "t_ns" in doc:
                if int(doc["t_ns"]) < self.seek_ns:
                    continue
                doc = {**doc, "t_ns": int(doc["t_ns"]) - self.seek_ns}
            out.append((t_log, doc))
        return out

    def _recorded_traffic(self) -> tuple[CanBatch, SerialBatch, SerialBatch]:
        can = read_can(self.reader, CAN_TX)
        can = can.take(np.argsort(can.t_ns, kind="stable"))
        # one round of the source's start-up, the counters after it moved back: this
        # replay's own start-up continues them (bench.run.startup)
        can = _ordered(drop_handshake_copies(can))
        if not self.lockstep or self.run_start.get("clock") != "lockstep":
            can = self._rebuild_bench_time(can)
        s = self.seek_ns
        return (
            rebase_can(can, s),
            rebase_serial(read_serial(self.reader, SERIAL_TX["imu"]), s, imu=True),
            rebase_serial(read_serial(self.reader, SERIAL_TX["gnss"]), s, imu=False),
        )

    def _rebuild_bench_time(self, can: CanBatch) -> CanBatch:
        """BENCH_TIME frames with this replay's lockstep bit (when the clock mode changed);
        their time and alive counter are kept."""
        return with_lockstep_bit(can, self.lockstep)[0]

    def metadata(self) -> dict[str, str]:
        keep = ("scenario", "scenario_title", "seed", "imu_rate_hz", "imu_grade", "truth_rate_hz", "case")
        return {
            "replay_of": str(self.path),
            "replay_mode": "verbatim" if self.faults is None else "re-encoded",
            **{k: str(self.run_start[k]) for k in keep if k in self.run_start},
            "replay_start_s": f"{self.seek_ns / 1e9:g}",
            "duration_s": f"{self.duration_ns / 1e9:.9g}",
            **self.provenance,
        }

    def declare(self, rec: RecordingWriter) -> None:
        for name, schema in self._schemas.items():
            rec.columnar_topic(name, schema, self._columns[name].dtype, description=f"copied from {self.path.name}")
        for topic, msgs in self._json.items():
            rec.json_topic(topic, self.topics[topic].schema, {"type": "object"})
            for t_log, doc in msgs:
                rec.write_json(topic, max(t_log - self.epoch_ns, 0), doc)
        rec.json_topic(FAULT_TOPIC, "bench.FaultWindow", FAULT_JSON_SCHEMA)
        for w in self.windows:
            rec.write_json(FAULT_TOPIC, w.start_ns, w.to_json())
        for name, data in self.reader.attachments().items():
            rec.attach(name, data, "application/toml" if name.endswith(".toml") else "application/octet-stream")

    def window(self, rec: RecordingWriter, t0_ns: int, t1_ns: int) -> Traffic:
        first = t0_ns == self.start_ns
        records: dict[str, Any] = {}
        for name, arr in self._columns.items():
            t = arr["t_ns"]
            lo = np.searchsorted(t, t0_ns, side="left" if first else "right")
            hi = np.searchsorted(t, t1_ns, side="right")
            part = arr[lo:hi]
            rec.write_block(name, part)
            records[name] = part
        if self._traffic is not None:
            can, imu, gnss = self._traffic
            return Traffic(
                slice_window(can, t0_ns, t1_ns, first),
                slice_window(imu, t0_ns, t1_ns, first),
                slice_window(gnss, t0_ns, t1_ns, first),
                np.zeros(0, WIRE_EVENT_DTYPE),
            )
        assert self.encoder is not None
        return self.encoder.window(records, t0_ns, t1_ns)

    def counts(self) -> dict[str, int]:
        return {k: len(v) for k, v in self._columns.items()}
