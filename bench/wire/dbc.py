"""The CAN part of the ICD, read from its DBC file with cantools.

``models/can/icd_1_0.dbc`` is the machine-readable form of ICD sections 2.1 and 2.2; this
module is the only place that reads it (and the only user of cantools in the bench). It
turns each message into a :class:`MessageSpec`: identifier, length, FD flag, cycle time
and its signals as bit :class:`~bench.wire.bits.Field` s with scale, unit and range, which
the vectorised codecs of :mod:`bench.wire.can` run on.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import cantools

from bench.errors import CodecError
from bench.paths import models_dir
from bench.wire.bits import Field

__all__ = ["SignalSpec", "MessageSpec", "dbc_path", "load_specs", "spec", "spec_by_id", "database"]


def dbc_path() -> Path:
    """The DBC of ICD 1.0: ``models/can/icd_1_0.dbc``."""
    return models_dir() / "can" / "icd_1_0.dbc"


@dataclass(frozen=True)
class SignalSpec:
    """One DBC signal: its bit field, physical = raw * scale + offset in ``unit``, allowed range."""

    field: Field
    scale: float
    offset: float
    unit: str
    minimum: float | None
    maximum: float | None
    choices: dict[int, str] = field(default_factory=dict)

    @property
    def name(self) -> str:
        """The DBC signal name."""
        return self.field.name

    @property
    def is_integer(self) -> bool:
        """Whether the physical value is the raw integer itself (scale 1, offset 0)."""
        return self.scale == 1 and self.offset == 0


@dataclass(frozen=True)
class MessageSpec:
    """One DBC message."""

    name: str
    frame_id: int
    length: int
    fd: bool
    cycle_ms: int | None
    senders: tuple[str, ...]
    signals: tuple[SignalSpec, ...]

    @property
    def fields(self) -> tuple[Field, ...]:
        """The bit fields of every signal."""
        return tuple(s.field for s in self.signals)

    def signal(self, name: str) -> SignalSpec:
        """The signal called ``name``."""
        for s in self.signals:
            if s.name == name:
                return s
        raise KeyError(f"{self.name} has no signal {name!r}; it has {', '.join(s.name for s in self.signals)}")


@cache
def database(path: str | None = None) -> cantools.database.can.Database:
    """The cantools database of the DBC (strict loading: overlapping signals are refused)."""
    return cantools.database.load_file(str(path or dbc_path()), strict=True)


def _signal_spec(sig) -> SignalSpec:
    if sig.byte_order != "little_endian":
        raise CodecError("format", f"signal {sig.name}: the ICD is little-endian, the DBC says {sig.byte_order}")
    if sig.is_float:
        raise CodecError("format", f"signal {sig.name}: the ICD has no floating-point fields")
    choices = {int(k): str(v) for k, v in (sig.choices or {}).items()}
    return SignalSpec(
        Field(sig.name, sig.start, sig.length, sig.is_signed),
        float(sig.scale),
        float(sig.offset),
        sig.unit or "",
        None if sig.minimum is None else float(sig.minimum),
        None if sig.maximum is None else float(sig.maximum),
        choices,
    )


@cache
def load_specs(path: str | None = None) -> dict[str, MessageSpec]:
    """Every message of the DBC, by name."""
    specs = {}
    for m in database(path).messages:
        specs[m.name] = MessageSpec(
            m.name,
            int(m.frame_id),
            int(m.length),
            bool(m.is_fd),
            None if m.cycle_time is None else int(m.cycle_time),
            tuple(m.senders),
            tuple(_signal_spec(s) for s in sorted(m.signals, key=lambda s: s.start)),
        )
    return specs


def spec(name: str) -> MessageSpec:
    """The message called ``name`` (``"ODOMETER"``)."""
    specs = load_specs()
    if name not in specs:
        raise CodecError("unknown_id", f"no message {name!r} in the ICD; known: {', '.join(specs)}")
    return specs[name]


def spec_by_id(frame_id: int) -> MessageSpec:
    """The message with identifier ``frame_id``."""
    for s in load_specs().values():
        if s.frame_id == frame_id:
            return s
    raise CodecError("unknown_id", f"identifier 0x{frame_id:03X} is not in the ICD")
