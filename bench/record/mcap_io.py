"""MCAP recordings: the one module that uses the ``mcap`` library.

Two kinds of topics:

* **columnar** topics carry blocks of samples as little-endian numpy structured arrays
  (schema and message encoding ``bench.columnar.v1``). The schema is JSON naming the
  fields, their types, shapes, units and frames, so any reader can decode a block with
  ``numpy.frombuffer(data, dtype)``; every record carries its own ``t_ns``. This is how
  every sample of a run fits in the file at the rates a bench runs at.
* **json** topics carry one JSON document per message (``jsonschema`` schemas), used for
  the Foxglove well-known schemas (``foxglove.LocationFix``, ``foxglove.PoseInFrame``) so
  a recording opens in Foxglove Studio with a map and plots, and for sparse events.

Message log times are UTC nanoseconds: the run's epoch (UTC of bench time zero) plus the
bench time of the first record in the message. Recordings are zstd-chunked with CRCs.
See ``docs/recording.md`` for the topic list.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np
from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, make_reader
from mcap.writer import CompressionType, Writer

from bench import __version__
from bench.errors import RecordingError

__all__ = [
    "COLUMNAR",
    "CHUNKS",
    "RecordingWriter",
    "RecordingReader",
    "TopicInfo",
    "dtype_to_json",
    "dtype_from_json",
]

#: Schema and message encoding of columnar blocks.
COLUMNAR = "bench.columnar.v1"
#: Schema and message encoding of byte chunks (serial traffic): ``u4 n``, then ``n``
#: little-endian ``i8`` times, ``n`` ``u4`` lengths, then the bytes of the chunks.
CHUNKS = "bench.chunks.v1"
PROFILE = "nav-hil-bench"


def dtype_to_json(dtype: np.dtype) -> list[list[Any]]:
    """Fields of a structured dtype as ``[name, format, shape]`` lists (little-endian)."""
    out: list[list[Any]] = []
    assert dtype.names is not None
    for name in dtype.names:
        sub = dtype.fields[name][0]  # type: ignore[index]
        base, shape = sub.subdtype if sub.subdtype else (sub, ())
        out.append([name, base.newbyteorder("<").str, list(shape)])
    return out


def dtype_from_json(fields: list[list[Any]]) -> np.dtype:
    """Inverse of :func:`dtype_to_json`."""
    return np.dtype([(n, f, tuple(s)) if s else (n, f) for n, f, s in fields])


@dataclass
class TopicInfo:
    """What a topic holds."""

    topic: str
    schema: str
    encoding: str
    messages: int
    metadata: dict[str, str]


class RecordingWriter:
    """Write one MCAP recording.

    Parameters
    ----------
    path:
        Output file (parent folders are created).
    epoch_ns:
        UTC of bench time zero, ns since 1970 (log times are epoch + bench time).
    chunk_size:
        Uncompressed bytes per chunk; a killed run loses at most the open chunk.
    """

    def __init__(self, path: str | Path, *, epoch_ns: int = 0, chunk_size: int = 1 << 20):
        self.path = Path(path)
        self.epoch_ns = int(epoch_ns)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            self._fh: IO[bytes] = self.path.open("wb")
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot write: {exc}") from None
        self._w = Writer(
            self._fh, chunk_size=chunk_size, compression=CompressionType.ZSTD, enable_crcs=True, enable_data_crcs=True
        )
        self._w.start(profile=PROFILE, library=f"nav-hil-bench/{__version__}")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, np.dtype | None]] = {}
        self._seq: dict[str, int] = {}
        self._closed = False

    # -- topics ---------------------------------------------------------------------------
    def columnar_topic(
        self,
        topic: str,
        schema_name: str,
        dtype: np.dtype,
        *,
        description: str = "",
        units: Mapping[str, str] | None = None,
    ) -> None:
        """Declare a columnar topic of records ``dtype`` (must have an int64 ``t_ns``)."""
        if topic in self._channels:
            return
        if dtype.names is None or "t_ns" not in dtype.names:
            raise RecordingError(f"{topic}: a columnar dtype needs a 't_ns' field")
        key = f"{COLUMNAR}:{schema_name}"
        if key not in self._schemas:
            schema = {"dtype": dtype_to_json(dtype), "units": dict(units or {}), "description": description}
            self._schemas[key] = self._w.register_schema(schema_name, COLUMNAR, json.dumps(schema).encode())
        cid = self._w.register_channel(topic, COLUMNAR, self._schemas[key], {"records": "numpy"})
        self._channels[topic] = (cid, np.dtype(dtype).newbyteorder("<"))
        self._seq[topic] = 0

    def json_topic(self, topic: str, schema_name: str, json_schema: Mapping[str, Any]) -> None:
        """Declare a JSON topic with a JSON-Schema (e.g. a Foxglove well-known schema)."""
        if topic in self._channels:
            return
        key = f"jsonschema:{schema_name}"
        if key not in self._schemas:
            self._schemas[key] = self._w.register_schema(schema_name, "jsonschema", json.dumps(json_schema).encode())
        cid = self._w.register_channel(topic, "json", self._schemas[key])
        self._channels[topic] = (cid, None)
        self._seq[topic] = 0

    def chunks_topic(self, topic: str, schema_name: str, *, description: str = "") -> None:
        """Declare a topic of time-stamped byte chunks (serial traffic in one direction)."""
        if topic in self._channels:
            return
        key = f"{CHUNKS}:{schema_name}"
        if key not in self._schemas:
            schema = {"layout": "u4 n; i8[n] t_ns; u4[n] length; bytes", "description": description}
            self._schemas[key] = self._w.register_schema(schema_name, CHUNKS, json.dumps(schema).encode())
        cid = self._w.register_channel(topic, CHUNKS, self._schemas[key])
        self._channels[topic] = (cid, None)
        self._seq[topic] = 0

    # -- messages -------------------------------------------------------------------------
    def write_chunks(self, topic: str, t_ns: np.ndarray, offsets: np.ndarray, buf: np.ndarray | bytes) -> None:
        """Write chunks ``buf[offsets[i]:offsets[i+1]]`` due or received at ``t_ns[i]``."""
        n = len(t_ns)
        if n == 0:
            return
        cid, _ = self._channels[topic]
        lengths = np.diff(np.asarray(offsets, dtype=np.int64)).astype("<u4")
        body = np.asarray(buf, dtype=np.uint8).tobytes() if not isinstance(buf, bytes) else buf
        data = (
            np.uint32(n).tobytes()
            + np.asarray(t_ns, dtype="<i8").tobytes()
            + lengths.tobytes()
            + body[int(offsets[0]) : int(offsets[-1])]
        )
        t = self.epoch_ns + int(t_ns[0])
        self._w.add_message(cid, log_time=t, data=data, publish_time=t, sequence=self._seq[topic])
        self._seq[topic] += 1

    def write_block(self, topic: str, records: np.ndarray) -> None:
        """Write a block of records (structured array of the topic's dtype)."""
        if len(records) == 0:
            return
        cid, dtype = self._channels[topic]
        assert dtype is not None, f"{topic} is not columnar"
        data = np.ascontiguousarray(records, dtype=dtype).tobytes()
        t = self.epoch_ns + int(records["t_ns"][0])
        self._w.add_message(cid, log_time=t, data=data, publish_time=t, sequence=self._seq[topic])
        self._seq[topic] += 1

    def write_json(self, topic: str, t_ns: int, obj: Any) -> None:
        """Write one JSON message at bench time ``t_ns``."""
        cid, _ = self._channels[topic]
        t = self.epoch_ns + int(t_ns)
        self._w.add_message(
            cid,
            log_time=t,
            data=json.dumps(obj, separators=(",", ":")).encode(),
            publish_time=t,
            sequence=self._seq[topic],
        )
        self._seq[topic] += 1

    def write_json_many(self, topic: str, t_ns: np.ndarray, objs: list[Any]) -> None:
        """Write many JSON messages (one per time)."""
        for t, obj in zip(t_ns, objs, strict=True):
            self.write_json(topic, int(t), obj)

    def attach(self, name: str, data: bytes, media_type: str = "text/plain") -> None:
        """Attach a file (test case, motion script, parameter set, DBC...)."""
        self._w.add_attachment(
            create_time=self.epoch_ns, log_time=self.epoch_ns, name=name, media_type=media_type, data=data
        )

    def metadata(self, name: str, values: Mapping[str, Any]) -> None:
        """Add a metadata record; values are stored as strings (JSON for non-strings)."""
        self._w.add_metadata(name, {k: v if isinstance(v, str) else json.dumps(v) for k, v in values.items()})

    # -- end ------------------------------------------------------------------------------
    def close(self, status: str = "complete", reason: str = "") -> None:
        """Finish the file with a final ``run_end`` metadata record; idempotent."""
        if self._closed:
            return
        self._closed = True
        try:
            self.metadata("run_end", {"status": status, "reason": reason})
            self._w.finish()
        finally:
            self._fh.close()

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: Any) -> None:
        if exc_type is None:
            self.close("complete")
        elif issubclass(exc_type, KeyboardInterrupt):
            self.close("interrupted", "KeyboardInterrupt")
        else:
            self.close("error", f"{exc_type.__name__}: {exc}")


class RecordingReader:
    """Read a recording: topics, columnar blocks as arrays, JSON messages, attachments.

    A file that was never finished (the writer was killed) is read sequentially up to
    its last complete chunk; :attr:`complete` tells which case applies.
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if not self.path.exists():
            raise RecordingError(f"{self.path}: file not found")
        self.complete = True
        try:
            with self.path.open("rb") as fh:
                summary = make_reader(fh).get_summary()
            if summary is None:
                self.complete = False
        except (McapError, ValueError, EOFError, AssertionError):
            self.complete = False
        self._schemas: dict[int, Any] = {}

    def _iter(self, topics: list[str] | None = None) -> Iterator[tuple[Any, Any, Any]]:
        with self.path.open("rb") as fh:
            if self.complete:
                yield from make_reader(fh, validate_crcs=True).iter_messages(topics=topics, log_time_order=False)
                return
            reader = NonSeekingReader(fh, validate_crcs=True)
            try:
                yield from reader.iter_messages(topics=topics, log_time_order=False)
            except (McapError, ValueError, EOFError, AssertionError):
                return  # truncated: everything before the damage has been returned

    def topics(self) -> dict[str, TopicInfo]:
        """Topic name -> what it holds (message counts by reading the file if unfinished)."""
        out: dict[str, TopicInfo] = {}
        if self.complete:
            with self.path.open("rb") as fh:
                summary = make_reader(fh).get_summary()
            assert summary is not None
            counts = summary.statistics.channel_message_counts if summary.statistics else {}
            for cid, ch in summary.channels.items():
                sch = summary.schemas.get(ch.schema_id)
                out[ch.topic] = TopicInfo(
                    ch.topic, sch.name if sch else "", ch.message_encoding, counts.get(cid, 0), dict(ch.metadata)
                )
            return out
        for schema, ch, _ in self._iter():
            info = out.get(ch.topic)
            if info is None:
                info = out[ch.topic] = TopicInfo(
                    ch.topic, schema.name if schema else "", ch.message_encoding, 0, dict(ch.metadata)
                )
            info.messages += 1
        return out

    def read_columnar(self, topic: str) -> np.ndarray:
        """All records of a columnar topic, concatenated in write order."""
        parts: list[np.ndarray] = []
        dtype: np.dtype | None = None
        for schema, ch, msg in self._iter([topic]):
            if ch.message_encoding != COLUMNAR:
                raise RecordingError(f"{self.path}: topic {topic} is {ch.message_encoding}, not columnar")
            if dtype is None:
                dtype = dtype_from_json(json.loads(schema.data)["dtype"])
            parts.append(np.frombuffer(msg.data, dtype=dtype))
        if dtype is None:
            raise RecordingError(f"{self.path}: no messages on topic {topic}")
        return np.concatenate(parts)

    def read_chunks(self, topic: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """All chunks of a chunk topic: ``(t_ns, offsets, buf)`` in write order."""
        times: list[np.ndarray] = []
        lengths: list[np.ndarray] = []
        bodies: list[bytes] = []
        for _, ch, msg in self._iter([topic]):
            if ch.message_encoding != CHUNKS:
                raise RecordingError(f"{self.path}: topic {topic} is {ch.message_encoding}, not byte chunks")
            data = bytes(msg.data)
            n = int(np.frombuffer(data[:4], "<u4")[0])
            times.append(np.frombuffer(data[4 : 4 + 8 * n], "<i8"))
            lengths.append(np.frombuffer(data[4 + 8 * n : 4 + 12 * n], "<u4").astype(np.int64))
            bodies.append(data[4 + 12 * n :])
        if not times:
            return np.zeros(0, np.int64), np.zeros(1, np.int64), np.zeros(0, np.uint8)
        lens = np.concatenate(lengths)
        offsets = np.zeros(len(lens) + 1, np.int64)
        np.cumsum(lens, out=offsets[1:])
        return np.concatenate(times), offsets, np.frombuffer(b"".join(bodies), np.uint8)

    def iter_json(self, topic: str) -> Iterator[tuple[int, Any]]:
        """(log time ns, document) of each message of a JSON topic."""
        for _, _, msg in self._iter([topic]):
            yield msg.log_time, json.loads(msg.data)

    def iter_raw(self, topics: list[str] | None = None) -> Iterator[tuple[str, int, bytes]]:
        """(topic, log time, payload bytes) of every message, in file order."""
        for _, ch, msg in self._iter(topics):
            yield ch.topic, msg.log_time, bytes(msg.data)

    def metadata(self) -> dict[str, dict[str, str]]:
        """Metadata records by name (the last of each name wins)."""
        out: dict[str, dict[str, str]] = {}
        with self.path.open("rb") as fh:
            reader = make_reader(fh) if self.complete else NonSeekingReader(fh)
            try:
                for m in reader.iter_metadata():
                    out[m.name] = dict(m.metadata)
            except (McapError, ValueError, EOFError, AssertionError):
                pass
        return out

    def attachments(self) -> dict[str, bytes]:
        """Attached files by name."""
        out: dict[str, bytes] = {}
        with self.path.open("rb") as fh:
            reader = make_reader(fh) if self.complete else NonSeekingReader(fh)
            try:
                for a in reader.iter_attachments():
                    out[a.name] = bytes(a.data)
            except (McapError, ValueError, EOFError, AssertionError):
                pass
        return out
