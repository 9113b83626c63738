"""Wire-level fault kinds: registration, checks of the windows, event records.

Importing this module registers the kinds (layer ``"wire"``) with
:func:`bench.faults.schedule.register_kind`; :mod:`bench.faults.wire` applies them.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from bench.errors import ConfigError
from bench.faults.schedule import FaultSchedule, FaultWindow, ParamSpec, register_kind
from bench.faults.wire_ops import CanAdapter, ImuAdapter, parse_signal
from bench.frames import CAN_FD_LENGTHS
from bench.topics import TopicSpec
from bench.wire.can import codec
from bench.wire.dbc import load_specs

__all__ = [
    "WIRE_KINDS",
    "WIRE_EVENT_DTYPE",
    "WIRE_EVENTS_TOPIC",
    "SERIAL_LINKS",
    "register_wire_kinds",
    "wire_windows",
    "events",
    "concat_events",
]

WIRE_KINDS = (
    "drop", "delay", "duplicate", "freeze", "offset", "scale", "corrupt_crc", "counter_stale", "counter_skip",
    "wrong_dlc", "garbage", "truncate", "bad_checksum", "silence", "baud_mismatch",
)  # fmt: skip
_CODE = {k: i for i, k in enumerate(WIRE_KINDS)}
#: The ICD's serial streams: baud and framing.
SERIAL_LINKS: dict[str, tuple[int, str]] = {"imu": (460_800, "8N1"), "gnss": (115_200, "8N1")}

#: One record per frame or chunk a fault acted on.
WIRE_EVENT_DTYPE = np.dtype(
    [
        ("t_ns", "<i8"),  # due time of the frame or chunk (bench time)
        ("t_out_ns", "<i8"),  # when it went out after the fault; -1 dropped
        ("fault_id", "<i4"),  # FaultWindow.id (the window names target and kind)
        ("kind", "u1"),  # index into WIRE_KINDS
        ("can_id", "<u4"),  # CAN identifier, 0 on serial streams
        ("value", "<f8"),  # kind-specific: delay ns, counter written, bytes kept or received, copy number
    ]
)
WIRE_EVENTS_TOPIC = TopicSpec(
    "/faults/wire",
    "bench.WireFaultEvent",
    WIRE_EVENT_DTYPE,
    "what each wire fault did to which frame or chunk (kind indexes " + ", ".join(WIRE_KINDS) + ")",
    {
        "t_ns": "ns",
        "t_out_ns": "ns (-1 dropped)",
        "fault_id": "window id",
        "kind": "WIRE_KINDS index",
        "can_id": "identifier",
        "value": "kind-specific",
    },
)

_P = ParamSpec


def register_wire_kinds() -> None:
    """Register every wire-level kind (idempotent; done on import)."""
    msg, ser, imu_t, gnss_t = ("can:*",), ("serial:*",), ("serial:imu",), ("serial:gnss",)
    reg = register_kind
    reg(
        "wire",
        msg + ser,
        "drop",
        {"probability": _P("dimensionless", "1", 1.0, "chance each frame is lost")},
        "frames or chunks are not sent",
    )
    reg(
        "wire",
        msg + ser,
        "delay",
        {
            "delay": _P("time", "s", 0.0, "added to every frame"),
            "jitter": _P("time", "s", 0.0, "plus uniform 0..jitter per frame"),
        },
        "frames leave late, first in first out per message or stream",
    )
    reg(
        "wire",
        msg + ser,
        "duplicate",
        {
            "copies": _P("integer", "", 1, "extra copies of each frame", "copies"),
            "gap": _P("time", "s", 0.0, "between a frame and each copy"),
        },
        "each frame is sent again",
    )
    reg("wire", msg + imu_t, "freeze", {}, "values frozen at the last frame before the window; counter runs")
    reg(
        "wire",
        msg + imu_t + gnss_t,
        "offset",
        {
            "signal": _P("text", "", None, "quantity, e.g. speed, dtheta[2], or on serial:gnss h, lat, speed"),
            "value": _P("dimensionless", "1", None, "added, in the signal's SI unit"),
        },
        "a signal is offset (the frame stays valid)",
    )
    reg(
        "wire",
        msg + imu_t + gnss_t,
        "scale",
        {
            "signal": _P("text", "", None, "quantity, e.g. speed, dvel[1], or on serial:gnss h, lat, speed"),
            "factor": _P("dimensionless", "1", None, "multiplies the signal"),
        },
        "a signal is scaled (the frame stays valid)",
    )
    reg("wire", msg + imu_t, "corrupt_crc", {}, "the CRC is wrong")
    reg("wire", msg + imu_t, "counter_stale", {}, "the counter stops; it resumes from there after the window")
    reg(
        "wire",
        msg + imu_t,
        "counter_skip",
        {"skip": _P("integer", "", 1, "extra counter steps per frame", "count")},
        "the counter jumps on every frame of the window",
    )
    reg(
        "wire",
        msg,
        "wrong_dlc",
        {"dlc": _P("integer", "", 7, "payload bytes sent")},
        "the frame is sent with another data length (cut or zero-padded)",
    )
    reg(
        "wire",
        ser,
        "garbage",
        {
            "length": _P("integer", "", 16, "bytes per burst", "burst"),
            "every": _P("time", "s", 0.0, "a burst every so often (0: one at the start)", "period"),
        },
        "random bytes between frames (never a frame start)",
    )
    reg(
        "wire",
        ser,
        "truncate",
        {"keep": _P("integer", "", 0, "bytes kept of each chunk (0: random)")},
        "chunks are cut short",
    )
    reg("wire", gnss_t, "bad_checksum", {}, "NMEA checksum wrong")
    reg("wire", ("can", *ser), "silence", {}, "nothing at all on the link")
    reg(
        "wire",
        ser,
        "baud_mismatch",
        {"baud": _P("integer", "", None, "the sender's actual baud rate", "baud")},
        "bytes sent at another baud rate, as the receiving UART reads them",
    )


register_wire_kinds()


def wire_windows(schedule: FaultSchedule | Iterable[FaultWindow] | None) -> list[FaultWindow]:
    """The wire-layer windows of a schedule, checked for what the registry cannot check."""
    if schedule is None:
        return []
    out = [w for w in schedule if w.layer == "wire"]
    names = set(load_specs())
    for w in out:
        where = f"fault {w.id} ({w.target} {w.kind})"
        if w.target.startswith("can:") and w.target != "can:*" and w.target[4:] not in names:
            raise ConfigError(f"{where}: no message {w.target[4:]!r} in the ICD; known: {', '.join(sorted(names))}")
        if w.kind in ("offset", "scale") and w.target == "serial:gnss":
            from bench.faults.wire_nmea import NMEA_SIGNALS

            if w.params["signal"] not in NMEA_SIGNALS:
                raise ConfigError(f"{where}: signal must be one of {', '.join(NMEA_SIGNALS)}, "
                                  f"found {w.params['signal']!r}")
        elif w.kind in ("offset", "scale"):  # on can:* the messages that carry the signal
            name, index = parse_signal(w.params["signal"])
            if w.target == "serial:imu":
                carriers = [ImuAdapter().signals()]
            else:
                msgs = sorted(names) if w.target == "can:*" else [w.target[4:]]
                carriers = [CanAdapter(codec(m)).signals() for m in msgs]
            if not any(name in sigs and (index is not None) == (sigs[name] > 1) for sigs in carriers):
                known = sorted({n for sigs in carriers for n in _sig_names(sigs)})
                raise ConfigError(f"{where}: signal must be one of {', '.join(known)}, found {w.params['signal']!r}")
        if w.kind == "wrong_dlc" and w.params["dlc"] not in CAN_FD_LENGTHS:
            raise ConfigError(f"{where}: dlc must be a CAN payload length {CAN_FD_LENGTHS}, found {w.params['dlc']}")
        if w.kind == "baud_mismatch" and w.params["baud"] <= 0:
            raise ConfigError(f"{where}: baud must be positive, found {w.params['baud']}")
        for key in ("copies", "skip", "length"):
            if key in w.params and w.params[key] < 1:
                raise ConfigError(f"{where}: {key} must be at least 1, found {w.params[key]}")
        if w.kind == "drop" and not 0.0 <= w.params["probability"] <= 1.0:
            raise ConfigError(f"{where}: probability must be within 0..1, found {w.params['probability']}")
    return out


def _sig_names(sigs: Mapping[str, int]) -> list[str]:
    return [n if k == 1 else f"{n}[0..{k - 1}]" for n, k in sigs.items()]


def events(t_ns, t_out, w: FaultWindow, can_id, value) -> np.ndarray:
    t_ns = np.atleast_1d(np.asarray(t_ns, np.int64))
    ev = np.zeros(t_ns.shape[0], WIRE_EVENT_DTYPE)
    ev["t_ns"], ev["t_out_ns"], ev["fault_id"], ev["kind"] = t_ns, t_out, w.id, _CODE[w.kind]
    ev["can_id"], ev["value"] = can_id, value
    return ev


def concat_events(events: list[np.ndarray]) -> np.ndarray:
    if not events:
        return np.zeros(0, WIRE_EVENT_DTYPE)
    ev = np.concatenate(events)
    return ev[np.argsort(ev["t_ns"], kind="stable")]
