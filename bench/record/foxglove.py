"""Foxglove views of a recording, encoded in protobuf (the one module that uses protobuf).

The views use the maintained Foxglove schemas (``foxglove_schemas_protobuf``:
``foxglove.LocationFix``, ``foxglove.PoseInFrame``, ``foxglove.FrameTransform``,
``foxglove.Log``) and, for the plot and event topics, small bench messages built at run
time with the ``google.protobuf`` descriptor API (package ``bench.foxglove``, one message
per schema, every field a plain scalar so Foxglove's plot panel can address it; their UTC
time is the message's log time, their ``t_s`` field bench time in s). Each
schema is written the way ``mcap_protobuf`` writes one: schema encoding ``protobuf``, the
data a serialized ``FileDescriptorSet`` of the message's file and its dependencies
(:func:`mcap_protobuf.schema.build_file_descriptor_set`), message encoding ``protobuf``,
schema name the message's full name.

What is in the views (which records, which frames) is decided above this layer
(:mod:`bench.scoring.views`); this module only encodes arrays into messages and writes
them as channels marked ``derived: true`` with the columnar ``source`` topics they were
made from. Times are bench time, ns; a message's log time (and the ``timestamp`` field of
the Foxglove schemas) is UTC: the recording's epoch plus bench time.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cache
from typing import Any

import numpy as np
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.LocationFix_pb2 import LocationFix
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from google.protobuf import descriptor_pb2, descriptor_pool
from google.protobuf.message_factory import GetMessageClass
from mcap_protobuf.schema import build_file_descriptor_set

from bench.record.writer import RecordingWriter

__all__ = [
    "PROTOBUF",
    "PACKAGE",
    "Fixes",
    "Poses",
    "LogLines",
    "Series",
    "Events",
    "ViewTopic",
    "COVARIANCE_UNKNOWN",
    "COVARIANCE_DIAGONAL_KNOWN",
    "COVARIANCE_KNOWN",
    "LOG_LEVELS",
    "series_class",
    "event_class",
    "encode",
    "write_views",
]

#: Schema and message encoding of every view.
PROTOBUF = "protobuf"
#: Protobuf package of the bench's own plot and event messages.
PACKAGE = "bench.foxglove"
COVARIANCE_UNKNOWN = int(LocationFix.PositionCovarianceType.UNKNOWN)
COVARIANCE_DIAGONAL_KNOWN = int(LocationFix.PositionCovarianceType.DIAGONAL_KNOWN)
COVARIANCE_KNOWN = int(LocationFix.PositionCovarianceType.KNOWN)
#: foxglove.Log levels by name.
LOG_LEVELS: dict[str, int] = {name: int(v) for name, v in Log.Level.items()}


@dataclass
class Fixes:
    """``foxglove.LocationFix`` series: N fixes at bench times ``t_ns``.

    ``lat, lon`` (N,) rad; ``h`` (N,) m; ``heading`` (N,) rad clockwise from north;
    ``vel_enu`` (N, 3) m/s; ``cov_enu`` (N, 3) variances E, N, U (m^2) on the diagonal
    and ``cov_type`` (N,) the LocationFix covariance type of each fix; ``color`` RGBA 0..1.
    """

    t_ns: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    heading: np.ndarray
    vel_enu: np.ndarray
    cov_enu: np.ndarray
    cov_type: np.ndarray
    frame_id: str
    color: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)


@dataclass
class Poses:
    """Body poses in a parent frame: ``pos`` (N, 3) m and ``q`` (N, 4) the body-to-parent
    rotation, scalar first. Written as ``foxglove.PoseInFrame`` (``frame_id`` = parent)
    or as ``foxglove.FrameTransform`` (``parent`` -> ``child``)."""

    t_ns: np.ndarray
    pos: np.ndarray
    q: np.ndarray
    parent: str
    child: str


@dataclass
class LogLines:
    """``foxglove.Log`` lines: level numbers (:data:`LOG_LEVELS`), names and texts."""

    t_ns: np.ndarray
    level: list[int]
    name: list[str]
    text: list[str]


@dataclass
class Series:
    """A plot series: message ``bench.foxglove.<schema>`` with ``t_s`` (bench time, s) and
    one scalar field per column (double, or fixed32 for integer and boolean columns); its
    UTC time is the message's log time."""

    schema: str
    t_ns: np.ndarray
    columns: dict[str, np.ndarray]


@dataclass
class Events:
    """``bench.foxglove.Event`` messages: ``kind`` (text), ``name`` (text), ``value``
    (a scalar to plot, e.g. 1 at a fault window's start and 0 at its end), ``text``."""

    t_ns: np.ndarray
    kind: list[str]
    name: list[str]
    value: np.ndarray
    text: list[str]


@dataclass
class ViewTopic:
    """One view channel: its topic, content and the columnar topics it was made from.
    ``as_transform`` writes :class:`Poses` as FrameTransform instead of PoseInFrame."""

    topic: str
    content: Fixes | Poses | LogLines | Series | Events
    source: Sequence[str]
    as_transform: bool = False
    metadata: dict[str, str] = field(default_factory=dict)


# -- message classes ------------------------------------------------------------------------
_POOL = descriptor_pool.DescriptorPool()


def _build(name: str, fields: tuple[tuple[str, int], ...]) -> Any:
    """The class of message ``bench.foxglove.<name>`` with ``fields`` numbered from 1."""
    f = descriptor_pb2.FileDescriptorProto(name=f"bench/foxglove/{name}.proto", package=PACKAGE, syntax="proto3")
    m = f.message_type.add(name=name)
    for i, (fname, ftype) in enumerate(fields, start=1):
        m.field.add(name=fname, number=i, type=ftype, label=descriptor_pb2.FieldDescriptorProto.LABEL_OPTIONAL)
    _POOL.Add(f)
    return GetMessageClass(_POOL.FindMessageTypeByName(f"{PACKAGE}.{name}"))


_DOUBLE = descriptor_pb2.FieldDescriptorProto.TYPE_DOUBLE
_FIXED32 = descriptor_pb2.FieldDescriptorProto.TYPE_FIXED32
_STRING = descriptor_pb2.FieldDescriptorProto.TYPE_STRING


@cache
def series_class(schema: str, fields: tuple[tuple[str, bool], ...]) -> Any:
    """The message class ``bench.foxglove.<schema>`` of a plot series: ``t_s`` (double,
    bench time in s), then each ``(name, integer)`` field (fixed32 if integer, else
    double). Fixed-width fields only, so that a series is encoded as one array."""
    return _build(schema, (("t_s", _DOUBLE), *((n, _FIXED32 if i else _DOUBLE) for n, i in fields)))


@cache
def event_class() -> Any:
    """The message class ``bench.foxglove.Event`` (t_s, kind, name, value, text; the
    timestamp is the message's log time)."""
    return _build("Event", (("t_s", _DOUBLE), ("kind", _STRING), ("name", _STRING), ("value", _DOUBLE),
                            ("text", _STRING)))


@cache
def _schema_data(cls: Any) -> bytes:
    return build_file_descriptor_set(message_class=cls).SerializeToString()


# -- encoding -------------------------------------------------------------------------------
def _stamp(msg: Any, utc_ns: int) -> None:
    msg.timestamp.seconds, msg.timestamp.nanos = divmod(utc_ns, 1_000_000_000)


def _fixes(epoch_ns: int, v: Fixes) -> list[bytes]:
    out = []
    utc = (epoch_ns + np.asarray(v.t_ns, np.int64)).tolist()
    lat, lon = np.degrees(v.lat).tolist(), np.degrees(v.lon).tolist()
    h, hd = np.asarray(v.h, float).tolist(), np.asarray(v.heading, float).tolist()
    vel, cov, ctype = np.asarray(v.vel_enu, float).tolist(), np.asarray(v.cov_enu, float).tolist(), list(v.cov_type)
    r, g, b, a = v.color
    for i, u in enumerate(utc):
        m = LocationFix(frame_id=v.frame_id, latitude=lat[i], longitude=lon[i], altitude=h[i], heading=hd[i],
                        position_covariance_type=int(ctype[i]))
        _stamp(m, u)
        c = cov[i]
        m.position_covariance.extend([c[0], 0.0, 0.0, 0.0, c[1], 0.0, 0.0, 0.0, c[2]])
        m.velocity.x, m.velocity.y, m.velocity.z = vel[i]
        m.color.r, m.color.g, m.color.b, m.color.a = r, g, b, a
        out.append(m.SerializeToString())
    return out


def _poses(epoch_ns: int, v: Poses, transform: bool) -> list[bytes]:
    out = []
    utc = (epoch_ns + np.asarray(v.t_ns, np.int64)).tolist()
    pos, q = np.asarray(v.pos, float).tolist(), np.asarray(v.q, float).tolist()
    for i, u in enumerate(utc):
        if transform:
            m = FrameTransform(parent_frame_id=v.parent, child_frame_id=v.child)
            t, r = m.translation, m.rotation
        else:
            m = PoseInFrame(frame_id=v.parent)
            t, r = m.pose.position, m.pose.orientation
        _stamp(m, u)
        t.x, t.y, t.z = pos[i]
        r.w, r.x, r.y, r.z = q[i]
        out.append(m.SerializeToString())
    return out


def _logs(epoch_ns: int, v: LogLines) -> list[bytes]:
    out = []
    for u, lvl, name, text in zip((epoch_ns + np.asarray(v.t_ns, np.int64)).tolist(), v.level, v.name, v.text,
                                  strict=True):
        m = Log(level=lvl, name=name, message=text)
        _stamp(m, u)
        out.append(m.SerializeToString())
    return out


def _series_fields(v: Series) -> tuple[tuple[str, bool], ...]:
    return tuple((k, np.issubdtype(np.asarray(c).dtype, np.integer) or np.asarray(c).dtype == bool)
                 for k, c in v.columns.items())


def _series(v: Series) -> tuple[Any, list[bytes]]:
    """A series' messages, every field written (proto3 parsers take explicit zeros), all
    of one length: encoded as the rows of one numpy record array (field tag, then the
    value: little-endian double, wire type 1, or fixed32, wire type 5)."""
    fields = (("t_s", False), *_series_fields(v))
    cls = series_class(v.schema, fields[1:])
    layout: list[tuple[str, str] | tuple[str, str, tuple[int]]] = []
    for num, (name, integer) in enumerate(fields, start=1):
        layout += [(f"__tag{num}", "u1", (len(_varint((num << 3) | (5 if integer else 1))),)),
                   (name, "<u4" if integer else "<f8")]
    rows = np.zeros(len(v.t_ns), np.dtype(layout))
    for num, (name, integer) in enumerate(fields, start=1):
        rows[f"__tag{num}"] = list(_varint((num << 3) | (5 if integer else 1)))
        value = np.asarray(v.t_ns, np.int64) * 1e-9 if name == "t_s" else np.asarray(v.columns[name])
        rows[name] = np.clip(value.astype(np.int64), 0, 2**32 - 1) if integer else value
    buf, size = rows.tobytes(), rows.dtype.itemsize
    return cls, [buf[i : i + size] for i in range(0, len(buf), size)]


def _varint(x: int) -> bytes:
    out = bytearray()
    while True:
        b, x = x & 0x7F, x >> 7
        out.append(b | (0x80 if x else 0))
        if not x:
            return bytes(out)


def _events(v: Events) -> list[bytes]:
    cls = event_class()
    t = (np.asarray(v.t_ns, np.int64) * 1e-9).tolist()
    rows = zip(t, v.kind, v.name, np.asarray(v.value, float).tolist(), v.text, strict=True)
    return [cls(t_s=tb, kind=kind, name=name, value=value, text=text).SerializeToString()
            for tb, kind, name, value, text in rows]


def encode(epoch_ns: int, view: ViewTopic) -> tuple[Any, list[bytes]]:
    """``(message class, serialized messages)`` of a view."""
    c = view.content
    if isinstance(c, Fixes):
        return LocationFix, _fixes(epoch_ns, c)
    if isinstance(c, Poses):
        return (FrameTransform if view.as_transform else PoseInFrame), _poses(epoch_ns, c, view.as_transform)
    if isinstance(c, LogLines):
        return Log, _logs(epoch_ns, c)
    if isinstance(c, Series):
        return _series(c)
    return event_class(), _events(c)


def write_views(rec: RecordingWriter, views: Sequence[ViewTopic], extra: Mapping[str, str] | None = None) -> int:
    """Write each view as a protobuf channel of ``rec`` (metadata ``derived: true``,
    ``source``: the columnar topics, comma-separated, and ``extra``); a view with no
    messages is left out. Returns the number of messages written."""
    n = 0
    for v in views:
        if len(v.content.t_ns) == 0:
            continue
        cls, payloads = encode(rec.epoch_ns, v)
        meta = {"derived": "true", "source": ",".join(v.source), **dict(extra or {}), **v.metadata}
        rec.encoded_topic(v.topic, cls.DESCRIPTOR.full_name, PROTOBUF, _schema_data(cls), PROTOBUF, meta)
        rec.write_encoded_many(v.topic, v.content.t_ns, payloads)
        n += len(payloads)
    return n
