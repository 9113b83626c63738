"""Reading a bench recording: topics, columnar blocks, byte chunks, JSON, metadata.

Built on :func:`bench.record.scan.scan`, so a recording is read as far as it goes: a
file that was never finished is read up to its last complete record, and a damaged one
past its damage. :attr:`RecordingReader.finished` and :attr:`RecordingReader.damage`
say which applies; nothing skipped goes unmentioned.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from bench.errors import RecordingError
from bench.record.layout import CHUNKS, COLUMNAR, TopicInfo, dtype_from_json
from bench.record.scan import Damage, FileIndex, scan

__all__ = ["RecordingReader"]


class RecordingReader:
    """Read a recording (see the module docstring).

    Raises :class:`~bench.errors.ConfigError` when the path is not a bench recording at
    all (missing, a directory or device, empty, not MCAP, another program's MCAP).

    Attributes
    ----------
    finished:
        The writer finished the file (its data end or footer is there); False for a run
        that was killed.
    complete:
        The same as ``finished`` (the older name).
    damage:
        What could not be read (:class:`~bench.record.scan.Damage`), in file order.
    tail:
        ``(offset, length)`` of the incomplete record an unfinished file ends with, if any.
    """

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._index: FileIndex = scan(self.path)
        self.finished = self._index.finished
        self.complete = self.finished
        self.damage: list[Damage] = list(self._index.damage)
        self.tail = self._index.tail
        self._by_topic = {ch.topic: cid for cid, ch in sorted(self._index.channels.items())}

    @property
    def intact(self) -> bool:
        """Finished and undamaged."""
        return self.finished and not self.damage

    @property
    def size(self) -> int:
        return self._index.size

    def close(self) -> None:
        """Release the file (idempotent; reading again afterwards is an error)."""
        self._index.close()

    def __enter__(self) -> RecordingReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def epoch_ns(self) -> int:
        """UTC of bench time zero (``run_start.epoch_utc_ns``), 0 if not recorded."""
        try:
            return int(self.metadata().get("run_start", {}).get("epoch_utc_ns", 0))
        except ValueError:
            return 0

    def damage_lines(self) -> list[str]:
        """One line per damaged stretch, times in bench time."""
        epoch = self.epoch_ns()
        return [d.text(epoch) for d in self.damage]

    # -- messages -------------------------------------------------------------------------
    def _channels(self, topics: list[str] | None) -> set[int] | None:
        if topics is None:
            return None
        return {cid for cid, ch in self._index.channels.items() if ch.topic in topics}

    def _iter(self, topics: list[str] | None = None) -> Iterator[tuple[Any, Any, int, bytes]]:
        """(schema, channel, log time, data) of every readable message, in file order."""
        idx = self._index
        for cid, log_time, data in idx.messages(self._channels(topics)):
            ch = idx.channels[cid]
            yield idx.schemas.get(ch.schema_id), ch, log_time, data

    def topics(self) -> dict[str, TopicInfo]:
        """Topic name -> what it holds (``messages``: those that could be read)."""
        out: dict[str, TopicInfo] = {}
        idx = self._index
        for cid, ch in sorted(idx.channels.items()):
            sch = idx.schemas.get(ch.schema_id)
            out[ch.topic] = TopicInfo(
                ch.topic, sch.name if sch else "", ch.message_encoding, idx.counts.get(cid, 0), dict(ch.metadata)
            )
        return out

    def read_columnar(self, topic: str) -> np.ndarray:
        """All readable records of a columnar topic, concatenated in write order (into one
        growing buffer, block by block: never the blocks and their concatenation at once)."""
        buf = bytearray()
        dtype: np.dtype | None = None
        for schema, ch, _, data in self._iter([topic]):
            if ch.message_encoding != COLUMNAR:
                raise RecordingError(f"{self.path}: topic {topic} is {ch.message_encoding}, not columnar")
            if dtype is None:
                try:
                    dtype = dtype_from_json(json.loads(schema.data)["dtype"])
                except (AttributeError, KeyError, TypeError, ValueError, RecursionError) as exc:
                    raise RecordingError(f"{self.path}: topic {topic}: its schema does not parse: {exc}") from None
            if len(data) % dtype.itemsize:
                raise RecordingError(f"{self.path}: topic {topic}: a block of {len(data)} B is not whole records")
            buf += data
        if dtype is None:
            raise RecordingError(f"{self.path}: no messages on topic {topic}")
        return np.frombuffer(buf, dtype=dtype)  # writable, as a concatenation is

    def read_chunks(self, topic: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """All chunks of a chunk topic: ``(t_ns, offsets, buf)`` in write order."""
        times: list[np.ndarray] = []
        lengths: list[np.ndarray] = []
        bodies: list[bytes] = []
        for _, ch, _, data in self._iter([topic]):
            if ch.message_encoding != CHUNKS:
                raise RecordingError(f"{self.path}: topic {topic} is {ch.message_encoding}, not byte chunks")
            n = int(np.frombuffer(data[:4], "<u4")[0]) if len(data) >= 4 else -1
            lens = np.frombuffer(data[4 + 8 * n : 4 + 12 * n], "<u4").astype(np.int64) if n >= 0 else None
            if lens is None or len(lens) != n or 4 + 12 * n + int(lens.sum()) != len(data):
                raise RecordingError(f"{self.path}: topic {topic}: a message of {len(data)} B does not hold its chunks")
            times.append(np.frombuffer(data[4 : 4 + 8 * n], "<i8"))
            lengths.append(lens)
            bodies.append(data[4 + 12 * n :])
        if not times:
            return np.zeros(0, np.int64), np.zeros(1, np.int64), np.zeros(0, np.uint8)
        lens = np.concatenate(lengths)
        offsets = np.zeros(len(lens) + 1, np.int64)
        np.cumsum(lens, out=offsets[1:])
        return np.concatenate(times), offsets, np.frombuffer(b"".join(bodies), np.uint8)

    def iter_json(self, topic: str) -> Iterator[tuple[int, Any]]:
        """(log time ns, document) of each message of a JSON topic."""
        for _, _, log_time, data in self._iter([topic]):
            try:
                doc = json.loads(data)
            except (ValueError, RecursionError) as exc:  # RecursionError: nested deeper than Python parses
                raise RecordingError(f"{self.path}: topic {topic}: a message is not JSON: "
                                     f"{exc if isinstance(exc, ValueError) else 'nested too deep'}") from None
            yield log_time, doc

    def iter_raw(self, topics: list[str] | None = None) -> Iterator[tuple[str, int, bytes]]:
        """(topic, log time, payload bytes) of every readable message, in file order."""
        for _, ch, log_time, data in self._iter(topics):
            yield ch.topic, log_time, data

    def metadata(self) -> dict[str, dict[str, str]]:
        """Metadata records by name (the last of each name wins)."""
        return {name: dict(values) for name, values in self._index.metadata}

    def attachments(self) -> dict[str, bytes]:
        """Attached files by name (damaged ones are listed in :attr:`damage`)."""
        return {name: self._index.attachment_data(off, n) for name, _, off, n in self._index.attachments}
