"""From samples to the wire: the bench's outgoing traffic of each window, encoded per the
ICD and passed through the wire-level faults.

Per window ``(t0, t1]``: the IMU frames on the ``imu`` line at their time of validity;
the fix epochs as NMEA sentences on the ``gnss`` line when they leave the receiver
(measurement time plus latency, possibly after the window: they are held until due);
ODOMETER, DOPPLER and DRIVER_INPUT at their sample times; BENCH_TIME every 10 ms (with
the lockstep bit in lockstep runs), BENCH_EPOCH every second, BENCH_CMD at the commanded
times. At equal times BENCH_TIME goes last, as ICD 6 requires of a lockstep step.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bench.faults.schedule import FaultSchedule
from bench.faults.wire import WIRE_EVENT_DTYPE, WireFaultInjector
from bench.frames import CanBatch, SerialBatch
from bench.sensors.base import SensorModel
from bench.sensors.bds import BdsReceiver
from bench.sensors.doppler import DopplerRadar
from bench.sensors.driver import DriverInput
from bench.sensors.imu.faulty import FaultyImu
from bench.sensors.imu.model import LaserImu
from bench.sensors.odometer import Odometer
from bench.wire import imu as imu_codec
from bench.wire import nmea
from bench.wire.can import CanEncoder, codec
from bench.wire.icd import CMD_RESET_FILTER, CMD_SWITCH_TO_GEOGRAPHIC, CMD_SWITCH_TO_GRID

__all__ = ["Traffic", "TrafficEncoder", "slice_window", "faulted", "BENCH_TIME_ID", "COMMAND_CODES"]

BENCH_TIME_ID = codec("BENCH_TIME").frame_id
#: BENCH_CMD codes by name (ICD 2.1).
COMMAND_CODES = {"grid": CMD_SWITCH_TO_GRID, "geographic": CMD_SWITCH_TO_GEOGRAPHIC, "reset": CMD_RESET_FILTER}
#: CAN messages from sensor records: sensor -> (message, {signal: record field}).
_CAN_SAMPLES = {
    "odometer": ("ODOMETER", {"pulse_count": "pulses", "speed": "speed", "reverse": "reverse", "valid": "valid"}),
    "doppler": ("DOPPLER", {"speed": "speed", "quality": "quality", "valid": "valid", "low_signal": "low_signal"}),
    "driver": (
        "DRIVER_INPUT",
        {"left_lever": "left_lever", "right_lever": "right_lever", "steering": "steering", "brake": "brake"},
    ),
}


@dataclass
class Traffic:
    """The outgoing traffic due in one window, each link in time order."""

    can: CanBatch
    imu: SerialBatch
    gnss: SerialBatch
    events: np.ndarray  # wire fault events (WIRE_EVENT_DTYPE)


def slice_window(batch, t0: int, t1: int, first: bool):
    """The frames or chunks of ``batch`` (time-ordered) in ``(t0, t1]`` (``[t0, t1]`` when ``first``)."""
    lo = np.searchsorted(batch.t_ns, t0, side="left" if first else "right")
    hi = np.searchsorted(batch.t_ns, t1, side="right")
    return batch.take(np.arange(lo, hi))


def faulted(injector: WireFaultInjector, can: CanBatch, imu: SerialBatch, gnss: SerialBatch, t1_ns: int) -> Traffic:
    """One window's traffic through the wire faults (frames a delay holds wait for later)."""
    can, ev_can = injector.can(can, until_ns=t1_ns)
    imu, ev_imu = injector.serial("imu", imu, until_ns=t1_ns)
    gnss, ev_gnss = injector.serial("gnss", gnss, until_ns=t1_ns)
    return Traffic(_ordered(can), imu, gnss, np.concatenate([ev_can, ev_imu, ev_gnss]))


def _ordered(batch: CanBatch) -> CanBatch:
    """Time order; at equal times by identifier, BENCH_TIME last (ICD 6)."""
    if len(batch) == 0:
        return batch
    order = np.lexsort((batch.can_id, (batch.can_id == BENCH_TIME_ID).astype(np.int8), batch.t_ns))
    return batch.take(order)


class TrafficEncoder:
    """Encodes a run's sensor records onto the ICD links, window by window.

    Parameters
    ----------
    models:
        The run's sensor models (their records arrive by topic ``/<name>``).
    epoch_ns:
        UTC of bench time zero (BENCH_EPOCH, NMEA time fields).
    lockstep:
        Set the lockstep bit of BENCH_TIME; wire faults then leave BENCH_TIME alone, and a
        fault aimed at it is refused (:func:`bench.faults.lockstep.refuse_lockstep_faults`).
    schedule, seed:
        The run's fault schedule and seed (wire-layer windows are applied).
    commands:
        ``(t_ns, code)`` BENCH_CMD events.
    talker:
        NMEA talker (``GB``, ``BD``, ``GN``).
    topics:
        Sensor kind (``imu``, ``doppler``, ``odometer``, ``bds``, ``driver``) -> the topic
        its records come on, for records not produced by ``models`` (replay).
    """

    def __init__(
        self,
        models: Sequence[SensorModel],
        *,
        epoch_ns: int,
        lockstep: bool,
        schedule: FaultSchedule,
        seed: int,
        commands: Sequence[tuple[int, int]] = (),
        talker: str = "GB",
        bench_time_period_ns: int = 10_000_000,
        epoch_period_ns: int = 1_000_000_000,
        topics: dict[str, str] | None = None,
    ):
        self.epoch_ns = int(epoch_ns)
        self.lockstep = lockstep
        self.talker = talker
        self.bench_time_period_ns = bench_time_period_ns
        self.epoch_period_ns = epoch_period_ns
        self.commands = sorted((int(t), int(c)) for t, c in commands)
        self.encoder = CanEncoder()
        self.injector = WireFaultInjector(schedule, seed, lockstep=lockstep)
        self._faulty = any(w.layer == "wire" for w in schedule)
        self._imu_counter = 0
        self._carry_th = np.zeros(3)
        self._carry_dv = np.zeros(3)
        self._held_gnss = SerialBatch.empty()
        self._topic: dict[str, str] = dict(topics or {})
        for m in models:
            base = m.imu if isinstance(m, FaultyImu) else m
            for cls, kind in (
                (LaserImu, "imu"),
                (DopplerRadar, "doppler"),
                (Odometer, "odometer"),
                (BdsReceiver, "bds"),
                (DriverInput, "driver"),
            ):
                if isinstance(base, cls) and kind not in self._topic:
                    self._topic[kind] = f"/{m.name}"

    def _periodic(self, period: int, t0: int, t1: int, first: bool) -> np.ndarray:
        k0 = t0 // period + (0 if first and t0 % period == 0 else 1)
        return np.arange(k0, t1 // period + 1, dtype=np.int64) * period

    def window(self, records: dict[str, np.ndarray], t0_ns: int, t1_ns: int) -> Traffic:
        """The traffic due in ``(t0, t1]`` (``[0, t1]`` for the first window)."""
        first = t0_ns == 0
        enc = self.encoder
        parts: list[CanBatch] = []
        for sensor, (message, fields) in _CAN_SAMPLES.items():
            rec = records.get(self._topic.get(sensor, ""))
            if rec is not None and len(rec):
                parts.append(enc.encode(message, rec["t_ns"], **{sig: rec[col] for sig, col in fields.items()}))
        t_ep = self._periodic(self.epoch_period_ns, t0_ns, t1_ns, first)
        if len(t_ep):
            parts.append(enc.encode("BENCH_EPOCH", t_ep, epoch_utc_ns=np.full(len(t_ep), self.epoch_ns)))
        cmds = [(t, c) for t, c in self.commands if (t0_ns < t <= t1_ns) or (first and t == 0)]
        if cmds:
            parts.append(
                enc.encode(
                    "BENCH_CMD", np.array([t for t, _ in cmds], np.int64), command=np.array([c for _, c in cmds])
                )
            )
        t_bt = self._periodic(self.bench_time_period_ns, t0_ns, t1_ns, first)
        if len(t_bt):
            parts.append(enc.encode("BENCH_TIME", t_bt, time_ns=t_bt, lockstep=np.full(len(t_bt), int(self.lockstep))))
        can = _ordered(CanBatch.concat(parts))
        imu = SerialBatch.empty()
        rec = records.get(self._topic.get("imu", ""))
        if rec is not None and len(rec):
            n = len(rec)
            counter = (self._imu_counter + np.arange(n)) % 256
            self._imu_counter = (self._imu_counter + n) % 256
            # the remainders carried from frame to frame, as the IMU's pulse counters keep them
            th, self._carry_th = imu_codec.carry_quantize(rec["dtheta"], imu_codec.DTHETA_LSB, self._carry_th)
            dv, self._carry_dv = imu_codec.carry_quantize(rec["dvel"], imu_codec.DVEL_LSB, self._carry_dv)
            imu = imu_codec.encode_batch(rec["t_ns"], th, dv, rec["status"], rec["temperature"], counter)
        gnss = self._gnss(records.get(self._topic.get("bds", "")), t1_ns)
        if self._faulty:
            return faulted(self.injector, can, imu, gnss, t1_ns)
        return Traffic(can, imu, gnss, np.zeros(0, WIRE_EVENT_DTYPE))

    def _gnss(self, rec: np.ndarray | None, t1_ns: int) -> SerialBatch:
        """NMEA chunks due by ``t1`` (later ones are held for the next window)."""
        batch = SerialBatch.empty()
        if rec is not None and len(rec):
            fixes = np.zeros(len(rec), nmea.GNSS_FIX_DTYPE)
            fixes["t_ns"] = rec["t_ns"]
            stamp = rec["stamp_ns"] if "stamp_ns" in (rec.dtype.names or ()) else rec["t_ns"]
            fixes["utc_ns"] = self.epoch_ns + stamp  # what the receiver stamps (time-tag error included)
            for f in ("lat", "lon", "h", "vel_n", "sigma_lat", "sigma_lon", "sigma_alt", "hdop"):
                fixes[f] = rec[f]
            fixes["sats"] = rec["num_sats"]
            fixes["quality"] = rec["fix_quality"]
            batch = nmea.encode_epochs(fixes, talker=self.talker, at_ns=rec["tx_ns"], outage_style=rec["outage_style"])
        if self._faulty:
            return batch  # the injector holds what is not yet due
        if len(self._held_gnss):
            batch = SerialBatch.concat([self._held_gnss, batch])
        due = batch.t_ns <= t1_ns
        self._held_gnss = batch.take(~due)
        return batch.take(due)
