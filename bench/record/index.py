"""What a scan of a recording found: its blocks, channels, metadata, and its damage.

:class:`FileIndex` keeps the file open and reads the chunks again on demand
(:meth:`FileIndex.messages`, damaged chunks skipped); :class:`Damage` describes one
stretch that could not be read.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from mcap.records import Channel, Schema

from bench.errors import RecordingError
from bench.record.framing import BadRecord, RecordFile, attachment_record, decompress, inner_messages

__all__ = ["Damage", "ChunkInfo", "Loose", "FileIndex"]

_CACHE_BYTES = 64 << 20  # decompressed chunks kept for the next read


@dataclass(frozen=True)
class Damage:
    """A stretch of the file that could not be read.

    ``start_ns``/``end_ns`` are message log times (UTC ns) of what was lost when known
    (``exact``: from the chunk header or the summary; otherwise the gap between the
    readable neighbours); ``topics`` the topics it held when known.
    """

    what: str
    offset: int
    length: int
    reason: str
    chunk: int | None = None
    start_ns: int | None = None
    end_ns: int | None = None
    exact: bool = True
    topics: tuple[str, ...] = ()
    messages: int | None = None

    def text(self, epoch_ns: int = 0) -> str:
        """One line: what, where, which span and topics, why."""
        out = f"{self.what} at byte {self.offset} ({self.length} B)"
        if self.start_ns is not None and self.end_ns is not None:
            a, b = (self.start_ns - epoch_ns) * 1e-9, (self.end_ns - epoch_ns) * 1e-9
            out += (f", messages logged at bench time {a:.3f}-{b:.3f} s" if self.exact
                    else f", between bench time {a:.3f} and {b:.3f} s")
        if self.messages is not None:
            out += f", {self.messages} messages"
        if self.topics:
            out += f" of {', '.join(self.topics)}"
        return f"{out}: {self.reason}"


@dataclass
class ChunkInfo:
    """A chunk as found: where, its header, and what it holds (channel id -> messages)."""

    number: int
    offset: int
    length: int
    start_ns: int | None
    end_ns: int | None
    counts: dict[int, int] = field(default_factory=dict)
    indexed: dict[int, int] = field(default_factory=dict)  # from its message index records
    damaged: str | None = None


@dataclass
class Loose:
    """A message record outside any chunk."""

    offset: int
    length: int
    channel: int


@dataclass
class FileIndex:
    """Everything one scan of a recording found (see the module docstring)."""

    path: Path
    size: int
    profile: str = ""
    library: str = ""
    finished: bool = False
    blocks: list[ChunkInfo | Loose] = field(default_factory=list)
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    metadata: list[tuple[str, dict[str, str]]] = field(default_factory=list)
    attachments: list[tuple[str, str, int, int]] = field(default_factory=list)  # name, type, offset, length
    damage: list[Damage] = field(default_factory=list)
    tail: tuple[int, int] | None = None  # (offset, length) of an unfinished record at the end
    counts: dict[int, int] = field(default_factory=dict)  # channel id -> readable messages
    readable: set[int] = field(default_factory=set)  # channels whose definition and schema are known
    _file: RecordFile | None = None
    _cache: dict[int, bytes] = field(default_factory=dict)

    @property
    def chunks(self) -> list[ChunkInfo]:
        return [b for b in self.blocks if isinstance(b, ChunkInfo)]

    def close(self) -> None:
        """Close the file (idempotent)."""
        if self._file is not None:
            self._file.close()
            self._file = None
        self._cache.clear()

    @property
    def file(self) -> RecordFile:
        if self._file is None:
            raise ValueError(f"{self.path}: the recording was closed")
        return self._file

    def messages(self, channels: set[int] | None = None) -> Iterator[tuple[int, int, bytes]]:
        """``(channel id, log time, data)`` of every readable message in file order
        (only of ``channels`` if given); damaged chunks are skipped."""
        wanted = self.readable if channels is None else channels & self.readable
        for block in self.blocks:
            if isinstance(block, Loose):
                if block.channel in wanted:
                    body = self._reread(block.offset + 9, block.length - 9)
                    cid, _, log_time, _ = struct.unpack_from("<HIQQ", body, 0)
                    yield cid, log_time, bytes(body[22:])
                continue
            if block.damaged is not None or not wanted.intersection(block.counts):
                continue
            try:
                data = self._inflate(block)
            except (BadRecord, OSError) as exc:
                raise RecordingError(
                    f"{self.path}: chunk {block.number} changed since the file was opened: {exc}"
                ) from None
            for cid, log_time, a, b in inner_messages(data):
                if cid in wanted:
                    yield cid, log_time, data[a:b]

    def attachment_data(self, offset: int, length: int) -> bytes:
        body = self._reread(offset + 9, length - 9)
        try:
            return bytes(attachment_record(body).data)
        except BadRecord as exc:
            raise RecordingError(f"{self.path}: the file changed since it was opened: {exc}") from None

    def _reread(self, pos: int, n: int) -> bytes:
        try:
            return self.file.read(pos, n)
        except (BadRecord, OSError) as exc:
            raise RecordingError(f"{self.path}: the file changed since it was opened: {exc}") from None

    def _inflate(self, chunk: ChunkInfo) -> bytes:
        if chunk.number in self._cache:
            return self._cache[chunk.number]
        data = decompress(self.file, chunk.offset, chunk.length)
        if sum(map(len, self._cache.values())) + len(data) <= _CACHE_BYTES:
            self._cache[chunk.number] = data
        return data
