"""Replay of field logs: a vehicle's CAN log and serial byte logs re-emitted into a DUT.

:class:`LogReplay` takes what a logger on a real vehicle (or a bench run's export) keeps:
a python-can log (ASC, BLF) of the CAN bus, the raw bytes of the ``imu`` line and of the
``gnss`` line; any of the three may be absent. It places every frame and byte at a bench
time, adds the bench's own frames the DUT needs and a field log lacks (BENCH_TIME every
10 ms, BENCH_EPOCH every second), optionally applies wire faults, and optionally writes a
truth track given with the logs so that the replay can be scored. The rules (time
alignment, epoch, grouping of NMEA epochs) are in docs/run_engine.md, "Replaying field
logs"; :mod:`bench.run.bytelogs` cuts the byte logs.

CAN frames: the bench-to-DUT messages of the ICD (BENCH_TIME, BENCH_EPOCH, BENCH_CMD,
ODOMETER, DRIVER_INPUT, DOPPLER) are re-emitted as logged, payloads untouched (bad CRCs
and counters included: they are what the vehicle sent); with ``can_ids="all"`` every
other classic frame too. DUT-to-bench messages (NAV_SOLUTION, NAV_QUALITY, DUT_READY) are
never re-emitted.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.errors import ConfigError
from bench.faults.schedule import FAULT_JSON_SCHEMA, FAULT_TOPIC, FaultSchedule
from bench.faults.wire import WIRE_EVENT_DTYPE, WireFaultInjector
from bench.frames import CanBatch, SerialBatch
from bench.record.mcap_io import RecordingWriter
from bench.run.bytelogs import NmeaLog, imu_log_chunks, read_nmea_log
from bench.run.fieldcan import BENCH_TO_DUT, DUT_TO_BENCH, place_can_log, with_lockstep_bit
from bench.run.fieldtruth import TruthTrack, TruthWriter
from bench.run.imu_rate import measure_stream
from bench.run.provider import COMMANDS_TOPIC, TrafficProvider
from bench.run.spec import BENCH_TIME_PERIOD_NS
from bench.run.traffic import BENCH_TIME_ID, COMMAND_CODES, Traffic, _ordered, faulted, slice_window
from bench.runinfo import DEFAULT_EPOCH, parse_epoch
from bench.wire.can import CanEncoder, codec

__all__ = ["FieldLogs", "LogReplay", "TruthTrack", "BENCH_TO_DUT", "DUT_TO_BENCH", "EPOCH_PERIOD_NS"]

EPOCH_PERIOD_NS = 1_000_000_000
_EPOCH_ID = codec("BENCH_EPOCH").frame_id
_CMD_ID = codec("BENCH_CMD").frame_id
_COMMAND_NAMES = {code: name for name, code in COMMAND_CODES.items()}
_MS = 1_000_000


@dataclass
class FieldLogs:
    """The logs of a drive and how to place them in bench time.

    Attributes
    ----------
    can, imu, gnss:
        python-can log (ASC, BLF, ...), IMU byte log, NMEA byte log; None when absent.
    epoch_ns:
        UTC of bench time zero, ns since 1970 (``--epoch``), for logs without BENCH_EPOCH.
    can_offset_ns:
        Bench time of the CAN log's first frame, for logs without BENCH_TIME (default 0;
        negative cuts the start of the log).
    can_ids:
        ``"icd"``: re-emit the bench-to-DUT ICD messages only; ``"all"``: every classic
        frame but the DUT's own.
    can_channel:
        Keep this channel of the log only (numbered 1, 2, ... as Vector tools do).
    imu_shift_ns:
        Added to every IMU frame's time of validity (whole microseconds; the frames are
        re-stamped and their CRC recomputed when not 0).
    gnss_latency_ns:
        Time from an NMEA epoch's measurement (its UTC time field) to its sentences on the line.
    imu_data, gnss_data:
        The lines' bytes converted from a log in another format (:mod:`bench.exchange.field_logs`);
        None: the file is the line's bytes.
    imu_format, gnss_format:
        The format of the files (``icd``/``nmea`` or what they were converted from).
    epoch_rule:
        How ``epoch_ns`` was found when the logs' own times gave it (None: ``--epoch``).
    figures:
        Figures of the conversion, kept in ``log_figures``.
    """

    can: Path | None = None
    imu: Path | None = None
    gnss: Path | None = None
    epoch_ns: int | None = None
    can_offset_ns: int | None = None
    can_ids: str = "icd"
    can_channel: int | None = None
    imu_shift_ns: int = 0
    gnss_latency_ns: int = 0
    imu_data: bytes | None = None
    gnss_data: bytes | None = None
    imu_format: str = "icd"
    gnss_format: str = "nmea"
    epoch_rule: str | None = None
    figures: dict[str, object] | None = None

    def files(self) -> dict[str, Path]:
        """The logs given, by kind."""
        return {k: Path(p) for k, p in (("can", self.can), ("imu", self.imu), ("gnss", self.gnss)) if p is not None}


def _read_bytes(path: Path, what: str) -> bytes:
    from bench.config.files import read_bytes  # a regular file of at most 1 GiB

    return read_bytes(path, what=what)


def _digest(path: Path) -> str:
    """SHA-256 of a log file; of a folder of logs (gnss-ins-sim output), of its files' names and
    digests in name order."""
    if path.is_dir():
        h = hashlib.sha256()
        for f in sorted(q for q in path.iterdir() if q.is_file()):
            h.update(f"{f.name}\0{_digest(f)}\n".encode())
        return h.hexdigest()
    with path.open("rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()


class LogReplay(TrafficProvider):
    """The traffic of field logs (see the module docstring and docs/run_engine.md).

    Parameters
    ----------
    logs:
        The logs and their placement options.
    lockstep:
        Clock mode of the replay (BENCH_TIME's lockstep bit, logged frames rebuilt if it differs).
    truth:
        A truth track of the drive, written as ``/truth`` at its rate; None: no truth.
    faults:
        Wire faults to apply (wire layer only).
    seed:
        Seed of the wire faults' random draws.
    start_ns:
        Seek: replay from this bench time on (a whole number of scheduler steps).
    """

    def __init__(
        self,
        logs: FieldLogs,
        *,
        lockstep: bool,
        truth: TruthTrack | None = None,
        faults: FaultSchedule | None = None,
        seed: int = 1,
        start_ns: int = 0,
    ):
        self.logs = logs
        self.lockstep = lockstep
        self.start_ns = int(start_ns)
        self.seed = seed
        self.facts: dict[str, object] = dict(logs.figures or {})  # figures of the logs
        self.warnings: list[str] = []  # what the user must be told (an assumed epoch)
        self.placement: dict[str, str] = {}  # how they were placed in bench time
        if not logs.files():
            raise ConfigError("a field-log replay needs at least one log: --can-log, --imu-log or --gnss-log")
        if logs.gnss_latency_ns < 0:
            raise ConfigError("the GNSS latency cannot be negative", key="gnss_latency")
        self.windows = list(faults or [])
        bad = [w for w in self.windows if w.layer != "wire"]
        if bad:
            raise ConfigError(
                f"fault {bad[0].id} ({bad[0].kind} on {bad[0].target}) acts on a sensor; a field-log replay "
                "re-emits logged frames and can only add wire faults",
                key="fault",
            )
        self.injector = (
            WireFaultInjector(FaultSchedule(self.windows), seed, lockstep=lockstep) if self.windows else None
        )
        can, logged_epochs = self._can() if logs.can else (CanBatch.empty(), np.zeros(0, np.int64))
        imu = self._imu() if logs.imu else SerialBatch.empty()
        self.imu_rate = measure_stream(imu, source=str(logs.imu))  # refuses a rate change; bench.run.imu_rate
        gnss_bytes = logs.gnss_data if logs.gnss_data is not None else (
            _read_bytes(logs.gnss, "NMEA byte log") if logs.gnss else None)
        nmea = read_nmea_log(gnss_bytes, file=str(logs.gnss)) if gnss_bytes is not None else None
        self.epoch_ns, self.epoch_source = self._epoch(logged_epochs, can, imu, nmea)
        gnss = self._gnss(nmea) if nmea is not None else SerialBatch.empty()
        last = max([int(b.t_ns[-1]) for b in (can, imu, gnss) if len(b)], default=0)
        self.duration_ns = -(-max(last, 1) // BENCH_TIME_PERIOD_NS) * BENCH_TIME_PERIOD_NS
        # generated frames first: at equal times BENCH_EPOCH goes before the logged frames (it wins
        # arbitration on a bus), BENCH_TIME after every frame of its time (ICD 6)
        logged, self.facts["bench_time_rebuilt"] = with_lockstep_bit(can, lockstep)
        self._can_traffic = _ordered(CanBatch.concat([*self._generated(can), logged]))
        self._imu_traffic = imu
        self._gnss_traffic = gnss
        self.commands = self._commands(self._can_traffic)
        self.truth = TruthWriter(truth, self.epoch_ns, self.duration_ns) if truth is not None else None

    # ------------------------------------------------------------------ CAN
    def _can(self) -> tuple[CanBatch, np.ndarray]:
        """The logged frames to re-emit, in bench time, and the logged BENCH_EPOCH values."""
        logs = self.logs
        assert logs.can is not None
        placed = place_can_log(logs.can, can_ids=logs.can_ids, channel=logs.can_channel, offset_ns=logs.can_offset_ns)
        self.facts["can"] = placed.facts
        self.placement["can_time"] = placed.rule
        self.placement["can_log_time_of_bench_zero_s"] = f"{placed.log_time_of_zero_ns / 1e9:.6f}"
        return placed.frames, placed.epochs

    def _generated(self, can: CanBatch) -> list[CanBatch]:
        """BENCH_TIME every 10 ms and BENCH_EPOCH every second over the run, each unless logged."""
        enc = CanEncoder()
        out = []
        made = []
        if not np.any(can.can_id == _EPOCH_ID):
            t = np.arange(0, self.duration_ns + 1, EPOCH_PERIOD_NS, dtype=np.int64)
            out.append(enc.encode("BENCH_EPOCH", t, epoch_utc_ns=np.full(t.size, self.epoch_ns)))
            made.append("BENCH_EPOCH")
        if not np.any(can.can_id == BENCH_TIME_ID):
            t = np.arange(0, self.duration_ns + 1, BENCH_TIME_PERIOD_NS, dtype=np.int64)
            out.append(enc.encode("BENCH_TIME", t, time_ns=t, lockstep=np.full(t.size, int(self.lockstep))))
            made.append("BENCH_TIME")
        self.placement["bench_frames"] = f"generated {', '.join(made)}" if made else "logged"
        return out

    @staticmethod
    def _commands(can: CanBatch) -> list[tuple[int, int]]:
        sel = np.flatnonzero(can.can_id == _CMD_ID)
        if sel.size == 0:
            return []
        values, status = codec("BENCH_CMD").decode(can.take(sel))
        return [
            (int(t), int(c))
            for t, c, s in zip(can.t_ns[sel].tolist(), values["command"].tolist(), status.tolist(), strict=True)
            if s == 0
        ]

    # ------------------------------------------------------------------ serial
    def _imu(self) -> SerialBatch:
        path = self.logs.imu
        assert path is not None
        data = self.logs.imu_data if self.logs.imu_data is not None else _read_bytes(path, "IMU byte log")
        batch, info = imu_log_chunks(data, file=str(path), shift_ns=self.logs.imu_shift_ns)
        self.facts["imu"] = info
        return batch

    def _epoch(self, logged: np.ndarray, can: CanBatch, imu: SerialBatch, nmea: NmeaLog | None) -> tuple[int, str]:
        """UTC of bench time zero (to the ms, as BENCH_EPOCH carries it) and where it came from."""
        given = self.logs.epoch_ns
        if logged.size:
            epoch = int(logged[0])
            if given is not None and abs(given - epoch) >= _MS:
                raise ConfigError(
                    f"the CAN log's BENCH_EPOCH says {epoch / 1e9:.3f} s since 1970, the epoch given says "
                    f"{given / 1e9:.3f} s: drop the epoch option or strip BENCH_EPOCH from the log",
                    file=str(self.logs.can),
                    key="epoch",
                )
            return epoch, "BENCH_EPOCH frames of the CAN log"
        if given is not None:
            return (given + _MS // 2) // _MS * _MS, self.logs.epoch_rule or "given (--epoch)"
        if nmea is not None:
            first_utc = int(nmea.epoch_utc_ns(None)[0])
            ref, what = (
                (int(can.t_ns[0]), "the CAN log's first frame")
                if len(can)
                else (int(imu.t_ns[0]), "the IMU log's first frame")
                if len(imu)
                else (0, "bench time zero")
            )
            return (first_utc - ref) // _MS * _MS, f"first NMEA epoch placed at {what} (bench time {ref / 1e9:g} s)"
        self.warnings.append(
            f"the logs carry no date (no BENCH_EPOCH, no NMEA, no --epoch): bench time zero is ASSUMED to be "
            f"{DEFAULT_EPOCH}, the bench's default epoch; the DUT's BENCH_EPOCH and every UTC of the replay are made "
            "up. Give --epoch (the UTC of the log's start)")
        return parse_epoch(DEFAULT_EPOCH), f"ASSUMED: default {DEFAULT_EPOCH} (no BENCH_EPOCH, no NMEA, none given)"

    def _gnss(self, nmea: NmeaLog) -> SerialBatch:
        utc = nmea.epoch_utc_ns(self.epoch_ns)[nmea.epoch_of]
        batch = nmea.batch(utc - self.epoch_ns + self.logs.gnss_latency_ns)
        early = batch.t_ns < 0
        self.facts["gnss"] = {**nmea.info, "before_bench_zero": int(early.sum())}
        if early.all():
            raise ConfigError(
                f"every NMEA epoch lies before bench time zero (UTC {self.epoch_ns / 1e9:.3f} s since 1970)",
                file=nmea.file,
            )
        return batch.take(~early) if early.any() else batch

    # ------------------------------------------------------------------ provider
    def metadata(self) -> dict[str, str]:
        files = self.logs.files()
        out: dict[str, str] = {
            "replay_of": ", ".join(str(p) for p in files.values()),
            "replay_mode": "field logs",
            "duration_s": f"{self.duration_ns / 1e9:.9g}",
            "epoch_source": self.epoch_source,
            "imu_format": self.logs.imu_format if self.logs.imu else "",
            "gnss_format": self.logs.gnss_format if self.logs.gnss else "",
            "gnss_latency_s": f"{self.logs.gnss_latency_ns / 1e9:g}",
            "imu_shift_s": f"{self.logs.imu_shift_ns / 1e9:g}",
            "log_figures": json.dumps(self.facts),
        }
        for kind, p in files.items():
            out[f"{kind}_log"] = str(p)
            out[f"{kind}_log_sha256"] = _digest(p)
        out.update(self.placement)
        if self.windows:
            out["seed"] = str(self.seed)
        out["truth"] = (
            self.truth.describe()
            if self.truth is not None
            else "none: field logs carry no truth; the recording holds the DUT output only (no accuracy scoring)"
        )
        return out

    def declare(self, rec: RecordingWriter) -> None:
        rec.json_topic(FAULT_TOPIC, "bench.FaultWindow", FAULT_JSON_SCHEMA)
        for w in self.windows:
            rec.write_json(FAULT_TOPIC, w.start_ns, w.to_json())
        rec.json_topic(COMMANDS_TOPIC, "bench.Command", {"type": "object"})
        for t, c in self.commands:
            rec.write_json(COMMANDS_TOPIC, t, {"t_ns": t, "command": _COMMAND_NAMES.get(c, str(c)), "code": c})
        if self.truth is not None:
            self.truth.declare(rec)

    def window(self, rec: RecordingWriter, t0_ns: int, t1_ns: int) -> Traffic:
        first = t0_ns == self.start_ns
        if self.truth is not None:
            self.truth.write(rec, t0_ns, t1_ns, first)
        can = slice_window(self._can_traffic, t0_ns, t1_ns, first)
        imu = slice_window(self._imu_traffic, t0_ns, t1_ns, first)
        gnss = slice_window(self._gnss_traffic, t0_ns, t1_ns, first)
        if self.injector is not None:
            return faulted(self.injector, can, imu, gnss, t1_ns)
        return Traffic(can, imu, gnss, np.zeros(0, WIRE_EVENT_DTYPE))

    def counts(self) -> dict[str, int]:
        return self.truth.counts() if self.truth is not None else {}
