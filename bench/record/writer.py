"""Writing one MCAP recording (the writer half of :mod:`bench.record.mcap_io`).

The file is claimed with :func:`bench.record.lock.claim` (one writer at a time, no
overwriting unless asked) and written in place. A write that fails (a full disk, a file
size limit, an I/O error) raises :class:`~bench.errors.RecordingError` once, ``recording
could not be written: No space left on device``; after that the writer drops every
write, :meth:`RecordingWriter.close` closes what it has, and :attr:`RecordingWriter.error`
keeps the reason. What reached the file before the failure stays readable (as an
unfinished recording).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import IO, Any

import numpy as np
from mcap.writer import CompressionType, Writer

from bench import __version__
from bench.errors import RecordingError
from bench.record.layout import CHUNKS, COLUMNAR, PROFILE, dtype_to_json
from bench.record.lock import claim
from bench.shield import shielded

__all__ = ["RecordingWriter"]


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
    overwrite:
        Replace an existing file at ``path`` (the bench commands pass False unless
        ``--force``). A file another process is writing is never replaced.

    Raises
    ------
    ConfigError
        When ``path`` cannot be written (see :func:`bench.record.lock.claim`).
    """

    def __init__(
        self, path: str | Path, *, epoch_ns: int = 0, chunk_size: int = 1 << 20, overwrite: bool = True
    ):
        self.path = Path(path)
        self.epoch_ns = int(epoch_ns)
        #: Why writing failed (None while it works).
        self.error: str | None = None
        self._closed = False
        self._fh: IO[bytes] = os.fdopen(claim(self.path, overwrite=overwrite), "wb")
        self._w = Writer(
            self._fh, chunk_size=chunk_size, compression=CompressionType.ZSTD, enable_crcs=True, enable_data_crcs=True
        )
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, np.dtype | None]] = {}
        self._seq: dict[str, int] = {}
        self._do(self._w.start, profile=PROFILE, library=f"nav-hil-bench/{__version__}")

    def _do(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """Call the library; an OSError becomes the writer's error (raised once). A signal
        does not cut the call (:mod:`bench.shield`): cut while the library compresses the
        open chunk, it would drop every message of that chunk from the file."""
        try:
            with shielded():
                return fn(*args, **kwargs)
        except OSError as exc:
            self.error = f"recording could not be written: {exc.strerror or exc}"
            raise RecordingError(f"{self.path}: {self.error}") from None

    @property
    def failed(self) -> bool:
        """True once a write failed (every later write is dropped)."""
        return self.error is not None

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
            self._schemas[key] = self._register(schema_name, COLUMNAR, json.dumps(schema).encode())
        cid = self._channel(topic, COLUMNAR, self._schemas[key], {"records": "numpy"})
        self._channels[topic] = (cid, np.dtype(dtype).newbyteorder("<"))
        self._seq[topic] = 0

    def json_topic(self, topic: str, schema_name: str, json_schema: Mapping[str, Any]) -> None:
        """Declare a JSON topic with a JSON-Schema (e.g. a Foxglove well-known schema)."""
        if topic in self._channels:
            return
        key = f"jsonschema:{schema_name}"
        if key not in self._schemas:
            self._schemas[key] = self._register(schema_name, "jsonschema", json.dumps(json_schema).encode())
        cid = self._channel(topic, "json", self._schemas[key], {})
        self._channels[topic] = (cid, None)
        self._seq[topic] = 0

    def chunks_topic(self, topic: str, schema_name: str, *, description: str = "") -> None:
        """Declare a topic of time-stamped byte chunks (serial traffic in one direction)."""
        if topic in self._channels:
            return
        key = f"{CHUNKS}:{schema_name}"
        if key not in self._schemas:
            schema = {"layout": "u4 n; i8[n] t_ns; u4[n] length; bytes", "description": description}
            self._schemas[key] = self._register(schema_name, CHUNKS, json.dumps(schema).encode())
        cid = self._channel(topic, CHUNKS, self._schemas[key], {})
        self._channels[topic] = (cid, None)
        self._seq[topic] = 0

    def encoded_topic(
        self,
        topic: str,
        schema_name: str,
        schema_encoding: str,
        schema_data: bytes,
        message_encoding: str,
        metadata: Mapping[str, str] | None = None,
    ) -> None:
        """Declare a topic of messages in another encoding (the protobuf Foxglove views of
        :mod:`bench.record.foxglove`); written with :meth:`write_encoded_many`."""
        if topic in self._channels:
            return
        key = f"{schema_encoding}:{schema_name}:{hashlib.sha256(schema_data).hexdigest()}"
        if not schema_name and not schema_encoding:  # a channel without a schema
            self._schemas[key] = 0
        elif key not in self._schemas:
            self._schemas[key] = self._register(schema_name, schema_encoding, schema_data)
        cid = self._channel(topic, message_encoding, self._schemas[key], dict(metadata or {}))
        self._channels[topic] = (cid, None)
        self._seq[topic] = 0

    def _register(self, name: str, encoding: str, data: bytes) -> int:
        if self.failed:
            return 0
        return int(self._do(self._w.register_schema, name, encoding, data))

    def _channel(self, topic: str, encoding: str, schema_id: int, metadata: dict[str, str]) -> int:
        if self.failed:
            return 0
        return int(self._do(self._w.register_channel, topic, encoding, schema_id, metadata))

    def _add(self, topic: str, t: int, data: bytes) -> None:
        if self.failed:
            return
        cid, _ = self._channels[topic]
        self._do(self._w.add_message, cid, log_time=t, data=data, publish_time=t, sequence=self._seq[topic])
        self._seq[topic] += 1

    # -- messages -------------------------------------------------------------------------
    def write_chunks(self, topic: str, t_ns: np.ndarray, offsets: np.ndarray, buf: np.ndarray | bytes) -> None:
        """Write chunks ``buf[offsets[i]:offsets[i+1]]`` due or received at ``t_ns[i]``."""
        n = len(t_ns)
        if n == 0:
            return
        lengths = np.diff(np.asarray(offsets, dtype=np.int64)).astype("<u4")
        body = np.asarray(buf, dtype=np.uint8).tobytes() if not isinstance(buf, bytes) else buf
        data = (
            np.uint32(n).tobytes()
            + np.asarray(t_ns, dtype="<i8").tobytes()
            + lengths.tobytes()
            + body[int(offsets[0]) : int(offsets[-1])]
        )
        self._add(topic, self.epoch_ns + int(t_ns[0]), data)

    def write_block(self, topic: str, records: np.ndarray) -> None:
        """Write a block of records (structured array of the topic's dtype)."""
        if len(records) == 0:
            return
        _, dtype = self._channels[topic]
        assert dtype is not None, f"{topic} is not columnar"
        data = np.ascontiguousarray(records, dtype=dtype).tobytes()
        self._add(topic, self.epoch_ns + int(records["t_ns"][0]), data)

    def write_json(self, topic: str, t_ns: int, obj: Any) -> None:
        """Write one JSON message at bench time ``t_ns``."""
        self._add(topic, self.epoch_ns + int(t_ns), json.dumps(obj, separators=(",", ":")).encode())

    def write_json_many(self, topic: str, t_ns: np.ndarray, objs: list[Any]) -> None:
        """Write many JSON messages (one per time)."""
        for t, obj in zip(t_ns, objs, strict=True):
            self.write_json(topic, int(t), obj)

    def write_encoded_many(self, topic: str, t_ns: np.ndarray, payloads: list[bytes]) -> None:
        """Write many messages already encoded in the topic's encoding (one per time), in
        batches: one library call guard per batch rather than per message."""
        times = (self.epoch_ns + np.asarray(t_ns, dtype=np.int64)).tolist()
        if len(times) != len(payloads):
            raise ValueError(f"{topic}: {len(times)} times for {len(payloads)} messages")
        if self.failed or not times:
            return
        cid, _ = self._channels[topic]
        add = self._w.add_message

        def batch(lo: int, hi: int) -> None:
            seq = self._seq[topic]
            for k in range(lo, hi):
                t = times[k]
                add(cid, log_time=t, data=payloads[k], publish_time=t, sequence=seq)
                seq += 1
                self._seq[topic] = seq

        for lo in range(0, len(times), 4096):
            self._do(batch, lo, min(lo + 4096, len(times)))

    def attach(self, name: str, data: bytes, media_type: str = "text/plain") -> None:
        """Attach a file (test case, motion script, parameter set, DBC...)."""
        if self.failed:
            return
        self._do(self._w.add_attachment, create_time=self.epoch_ns, log_time=self.epoch_ns, name=name,
                 media_type=media_type, data=data)

    def metadata(self, name: str, values: Mapping[str, Any]) -> None:
        """Add a metadata record; values are stored as strings (JSON for non-strings)."""
        if self.failed:
            return
        self._do(self._w.add_metadata, name, {k: v if isinstance(v, str) else json.dumps(v) for k, v in values.items()})

    def flush(self) -> None:
        """Write the open chunk and everything buffered to the file, so that a reader sees
        every message written so far (the file stays unfinished until :meth:`close`)."""
        if self.failed or self._closed:
            return
        self._do(self._w.flush)

    # -- end ------------------------------------------------------------------------------
    def close(self, status: str = "complete", reason: str = "") -> None:
        """Finish the file with a final ``run_end`` metadata record; idempotent.

        Never raises for a write that fails: :attr:`error` says why the file could not be
        finished (it is then closed as far as it got)."""
        if self._closed:
            return
        self._closed = True
        try:
            if not self.failed:
                try:
                    self._do(self.metadata, "run_end", {"status": status, "reason": reason})
                    self._do(self._w.finish)
                    self._do(self._fh.flush)
                except RecordingError:
                    pass
        finally:
            try:
                self._fh.close()
            except OSError as exc:  # the last buffered bytes could not be written
                self.error = self.error or f"recording could not be written: {exc.strerror or exc}"

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: Any) -> None:
        if exc_type is None:
            self.close("complete")
            if self.error is not None:
                raise RecordingError(f"{self.path}: {self.error}")
        elif issubclass(exc_type, KeyboardInterrupt):
            self.close("interrupted", "KeyboardInterrupt")
        else:
            self.close("error", f"{exc_type.__name__}: {exc}")
