"""An MCAP file read record by record, past damage: what is readable, what was skipped.

The ``mcap`` library's readers stop at the first bad byte (or raise). A recording is
evidence, so this scanner reads every record it can and names every one it cannot:

* each record is framed by its opcode and length and parsed within that length, so a
  bad record is skipped whole and the next one is read;
* a chunk is decompressed and its CRC checked (the library's
  ``get_chunk_data_stream``); a chunk that fails is skipped, counted, and described by
  its header (offset, length, message-time span) and by the message indexes that follow
  it (its topics);
* after a bad record length the scanner resynchronises on the next position where a
  plausible record starts (a known opcode, a length within the file, a body that parses,
  and a plausible record or the end right after it);
* a finished file's data-section CRC, summary CRC and footer are checked; a missing
  footer after the data end, or a damaged summary, is damage too.

A file that was never finished (the writer was killed) has no data end: it is read up to
its last complete record, and the incomplete record at its end is reported as its
``tail``, not as damage. :func:`scan` returns a :class:`FileIndex` of everything found;
the chunks' contents are read again on demand (:meth:`FileIndex.messages`).
"""

from __future__ import annotations

import os
import stat
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path
from typing import Any

import numpy as np
from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel, Chunk, Metadata, Schema
from mcap.stream_reader import get_chunk_data_stream

from bench.errors import ConfigError, RecordingError
from bench.record.layout import MAGIC, PROFILE

__all__ = ["Damage", "ChunkInfo", "FileIndex", "scan"]

_OPCODES = np.array(sorted(int(o) for o in Opcode), dtype=np.uint8)
_KNOWN = frozenset(int(o) for o in Opcode)
_MAX_UNCOMPRESSED = 1 << 30  # a chunk header claiming more is damaged
_CACHE_BYTES = 64 << 20  # decompressed chunks kept for the next read


class _Bad(Exception):  # noqa: N818 - internal, never leaves this module
    """A record body that does not parse (the reason is the message)."""


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
class _Loose:
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
    blocks: list[ChunkInfo | _Loose] = field(default_factory=list)
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    metadata: list[tuple[str, dict[str, str]]] = field(default_factory=list)
    attachments: list[tuple[str, str, int, int]] = field(default_factory=list)  # name, type, offset, length
    damage: list[Damage] = field(default_factory=list)
    tail: tuple[int, int] | None = None  # (offset, length) of an unfinished record at the end
    counts: dict[int, int] = field(default_factory=dict)  # channel id -> readable messages
    readable: set[int] = field(default_factory=set)  # channels whose definition and schema are known
    _file: _File | None = None
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
    def file(self) -> _File:
        if self._file is None:
            raise ValueError(f"{self.path}: the recording was closed")
        return self._file

    def messages(self, channels: set[int] | None = None) -> Iterator[tuple[int, int, bytes]]:
        """``(channel id, log time, data)`` of every readable message in file order
        (only of ``channels`` if given); damaged chunks are skipped."""
        wanted = self.readable if channels is None else channels & self.readable
        for block in self.blocks:
            if isinstance(block, _Loose):
                if block.channel in wanted:
                    body = self._reread(block.offset + 9, block.length - 9)
                    cid, _, log_time, _ = struct.unpack_from("<HIQQ", body, 0)
                    yield cid, log_time, bytes(body[22:])
                continue
            if block.damaged is not None or not wanted.intersection(block.counts):
                continue
            try:
                data = self._inflate(block)
            except (_Bad, OSError) as exc:
                raise RecordingError(
                    f"{self.path}: chunk {block.number} changed since the file was opened: {exc}"
                ) from None
            for cid, log_time, a, b in _inner_messages(data):
                if cid in wanted:
                    yield cid, log_time, data[a:b]

    def attachment_data(self, offset: int, length: int) -> bytes:
        body = self._reread(offset + 9, length - 9)
        try:
            return bytes(_attachment(body).data)
        except _Bad as exc:
            raise RecordingError(f"{self.path}: the file changed since it was opened: {exc}") from None

    def _reread(self, pos: int, n: int) -> bytes:
        try:
            return self.file.read(pos, n)
        except (_Bad, OSError) as exc:
            raise RecordingError(f"{self.path}: the file changed since it was opened: {exc}") from None

    def _inflate(self, chunk: ChunkInfo) -> bytes:
        if chunk.number in self._cache:
            return self._cache[chunk.number]
        data = _decompress(self.file, chunk.offset, chunk.length)
        if sum(map(len, self._cache.values())) + len(data) <= _CACHE_BYTES:
            self._cache[chunk.number] = data
        return data


class _File:
    """Positioned reads of an open file (a short read past a truncation raises _Bad)."""

    def __init__(self, fh: Any, size: int):
        self.fh = fh
        self.fd = fh.fileno()
        self.size = size

    def read(self, pos: int, n: int) -> bytes:
        out = os.pread(self.fd, n, pos) if n > 0 else b""
        if len(out) != max(n, 0):
            raise _Bad(f"the file ends at byte {pos + len(out)}, inside a record")
        return out

    def unpack(self, fmt: str, pos: int) -> tuple[Any, ...]:
        return struct.unpack(fmt, self.read(pos, struct.calcsize(fmt)))

    def crc(self, start: int, end: int) -> int:
        crc, pos = 0, start
        while pos < end:
            n = min(16 << 20, end - pos)
            crc = zlib.crc32(self.read(pos, n), crc)
            pos += n
        return crc

    def close(self) -> None:
        self.fh.close()


# -- record bodies -------------------------------------------------------------------------
def _chunk_header(f: _File, pos: int, length: int) -> tuple[int, int, int, int, str, int, int]:
    """``(start, end, uncompressed size, crc, compression, data offset, data length)`` of the
    chunk record at ``pos`` (its body is ``length`` bytes)."""
    body = pos + 9
    if length < 40:
        raise _Bad("chunk record too short")
    head = f.read(body, min(length, 48))
    start, end, usize, crc, clen = struct.unpack_from("<QQQII", head, 0)
    if clen > 8 or 32 + clen + 8 > length:
        raise _Bad(f"bad compression field length {clen}")
    try:
        comp = head[32 : 32 + clen].decode("ascii")
    except UnicodeDecodeError:
        raise _Bad("compression name is not ASCII") from None
    if comp not in ("", "zstd", "lz4"):
        raise _Bad(f"unknown compression {comp!r}")
    (dlen,) = struct.unpack_from("<Q", head, 32 + clen)
    data = body + 32 + clen + 8
    if data + dlen > body + length:
        raise _Bad(f"chunk data of {dlen} B runs past its record ({length} B)")
    if usize > _MAX_UNCOMPRESSED or start > end:
        raise _Bad(f"implausible chunk header (uncompressed {usize} B, times {start}..{end})")
    return start, end, usize, crc, comp, data, dlen


def _decompress(f: _File, pos: int, length: int) -> bytes:
    """The uncompressed records of the chunk record at ``pos``, CRC checked (or _Bad)."""
    start, end, usize, crc, comp, data, dlen = _chunk_header(f, pos, length - 9)
    chunk = Chunk(compression=comp, data=f.read(data, dlen), message_end_time=end,
                  message_start_time=start, uncompressed_crc=crc, uncompressed_size=usize)
    try:
        stream, n = get_chunk_data_stream(chunk, validate_crc=True)
        out = stream.read(n) if n else b""
    except Exception as exc:  # CRC mismatch, a broken zstd/lz4 frame, a missing codec
        raise _Bad(_reason(exc)) from None
    if len(out) != usize:
        raise _Bad(f"decompressed to {len(out)} B, the header says {usize} B")
    return out


def _reason(exc: BaseException) -> str:
    text = str(exc) or type(exc).__name__
    if "crc" in text.lower():
        return f"CRC mismatch ({text})"
    return f"cannot be decompressed ({type(exc).__name__}: {text})"


def _inner_messages(data: bytes) -> Iterator[tuple[int, int, int, int]]:
    """``(channel id, log time, data start, data end)`` of the message records in
    uncompressed chunk records (already validated by :func:`_inner_records`)."""
    pos, n = 0, len(data)
    while pos < n:
        op = data[pos]
        (length,) = struct.unpack_from("<Q", data, pos + 1)
        if op == Opcode.MESSAGE:
            cid, _, log_time, _ = struct.unpack_from("<HIQQ", data, pos + 9)
            yield cid, log_time, pos + 9 + 22, pos + 9 + length
        pos += 9 + length


def _inner_records(data: bytes) -> tuple[dict[int, int], list[Schema], list[Channel]]:
    """Messages per channel, schemas and channels of uncompressed chunk records (or _Bad)."""
    counts: dict[int, int] = {}
    schemas: list[Schema] = []
    channels: list[Channel] = []
    pos, n = 0, len(data)
    while pos < n:
        if pos + 9 > n:
            raise _Bad("a record inside the chunk is cut short")
        op = data[pos]
        (length,) = struct.unpack_from("<Q", data, pos + 1)
        if pos + 9 + length > n:
            raise _Bad(f"a record inside the chunk claims {length} B past the chunk's end")
        if op == Opcode.MESSAGE:
            if length < 22:
                raise _Bad("a message record inside the chunk is too short")
            (cid,) = struct.unpack_from("<H", data, pos + 9)
            counts[cid] = counts.get(cid, 0) + 1
        elif op == Opcode.SCHEMA:
            schemas.append(_parse(Schema, data[pos + 9 : pos + 9 + length]))
        elif op == Opcode.CHANNEL:
            channels.append(_parse(Channel, data[pos + 9 : pos + 9 + length]))
        pos += 9 + length
    return counts, schemas, channels


def _parse(kind: Any, body: bytes) -> Any:
    """A record body parsed by the library's reader, bounded by its length (or _Bad)."""
    try:
        return kind.read(ReadDataStream(BytesIO(body)))
    except Exception as exc:  # the library raises EndOfFile, struct.error, UnicodeDecodeError...
        raise _Bad(f"{kind.__name__} record does not parse ({type(exc).__name__})") from None


def _check_body(f: _File, pos: int, op: int, length: int) -> None:
    """Cheap plausibility of a record body (used to resynchronise); raises _Bad."""
    if op == Opcode.CHUNK:
        _chunk_header(f, pos, length)
        return
    body = f.read(pos + 9, length) if op != Opcode.MESSAGE else f.read(pos + 9, min(length, 22))
    if op == Opcode.MESSAGE_INDEX:
        if length < 6:
            raise _Bad("message index too short")
        _, n = struct.unpack_from("<HI", body, 0)
        if n % 16 or 6 + n > length:
            raise _Bad("message index length")
    elif op == Opcode.DATA_END:
        if length != 4:
            raise _Bad("data end length")
    elif op == Opcode.FOOTER:
        if length != 20:
            raise _Bad("footer length")
    elif op == Opcode.METADATA:
        _parse(Metadata, body)
    elif op == Opcode.ATTACHMENT:
        _attachment(body)
    elif op == Opcode.SCHEMA:
        _parse(Schema, body)
    elif op == Opcode.CHANNEL:
        _parse(Channel, body)
    elif op == Opcode.MESSAGE and length < 22:
        raise _Bad("message too short")


def _attachment(body: bytes) -> Attachment:
    rec = _parse(Attachment, body)
    (crc,) = struct.unpack_from("<I", body, len(body) - 4)
    if crc and zlib.crc32(body[:-4]) != crc:
        raise _Bad(f"attachment {rec.name!r}: CRC mismatch")
    return rec


# -- the scan ----------------------------------------------------------------------------------
def _preview(head: bytes) -> str:
    if all(32 <= c < 127 for c in head):
        return repr(head.decode("ascii"))
    return "bytes " + head.hex(" ")


def _open(path: Path) -> _File:
    """The recording opened for reading, or ConfigError naming what the path is."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise ConfigError("no such file", file=str(path)) from None
    except OSError as exc:
        raise ConfigError(f"cannot read it: {exc.strerror}", file=str(path)) from None
    if not stat.S_ISREG(st.st_mode):
        kind = (
            "a directory" if stat.S_ISDIR(st.st_mode)
            else "a FIFO" if stat.S_ISFIFO(st.st_mode)
            else "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode)
            else "not a regular file"
        )
        raise ConfigError(f"is {kind}, not an MCAP recording", file=str(path))
    if st.st_size == 0:
        raise ConfigError("is empty, not an MCAP recording", file=str(path))
    try:
        fh = open(path, "rb")  # noqa: SIM115 - owned by the returned _File
    except OSError as exc:
        raise ConfigError(f"cannot read it: {exc.strerror or exc}", file=str(path)) from None
    try:
        head = fh.read(8)
    except OSError as exc:
        fh.close()
        raise ConfigError(f"cannot read it: {exc.strerror or exc}", file=str(path)) from None
    if head != MAGIC:
        fh.close()
        raise ConfigError(f"starts with {_preview(head)}, not the MCAP magic: not a recording", file=str(path))
    return _File(fh, st.st_size)


def scan(path: str | Path) -> FileIndex:
    """Scan a bench recording (see the module docstring).

    Raises
    ------
    ConfigError
        The path is not a regular file, is empty, is not an MCAP file, or is an MCAP file of
        another profile (another program's): it says what it found.
    """
    path = Path(path)
    f = _open(path)
    idx = FileIndex(path, f.size, _file=f)
    try:
        _Scanner(idx, f).run()
    except BaseException:
        idx.close()
        raise
    return idx


class _Scanner:
    def __init__(self, idx: FileIndex, f: _File):
        self.idx = idx
        self.f = f
        self.size = idx.size
        self.footer: tuple[int, int, int] | None = None  # summary start, summary offset start, crc
        self.limit = self.size
        if self.size >= 8 + 37 and f.read(self.size - 8, 8) == MAGIC:
            self.limit = self.size - 8
            end = self.size - 37
            op, length = f.unpack("<BQ", end)
            if op == Opcode.FOOTER and length == 20:
                self.footer = f.unpack("<QQI", end + 9)
                self.limit = end
        self.data_end: int | None = None
        self.summary_read = False
        self.summary_chunks: list[tuple[int, int, int, int, tuple[int, ...]]] = []
        self.summary_channels: dict[int, Channel] = {}
        self.summary_schemas: dict[int, Schema] = {}

    def fail(self, what: str, offset: int, length: int, reason: str, **kw: Any) -> None:
        self.idx.damage.append(Damage(what, offset, length, reason, **kw))

    # -- header -------------------------------------------------------------------------
    def header(self) -> int:
        f, path = self.f, str(self.idx.path)
        if self.size < 8 + 9 or f.unpack("<B", 8)[0] != Opcode.HEADER:
            raise ConfigError("an MCAP file without a header record: not a bench recording", file=path)
        (length,) = f.unpack("<Q", 9)
        if 17 + length > self.size or length > 1 << 20:
            raise ConfigError("an MCAP file whose header record is cut short: not a bench recording", file=path)
        try:
            body = ReadDataStream(BytesIO(f.read(17, length)))
            profile, library = body.read_prefixed_string(), body.read_prefixed_string()
        except Exception:
            raise ConfigError("an MCAP file whose header does not parse: not a bench recording", file=path) from None
        if profile != PROFILE:
            raise ConfigError(
                f"an MCAP file of profile {profile!r} written by {library!r}, not a bench recording "
                f"(profile {PROFILE!r})",
                file=path,
            )
        self.idx.profile, self.idx.library = profile, library
        return 17 + length

    # -- the records ----------------------------------------------------------------------
    def run(self) -> None:
        pos = self.header()
        while pos < self.limit:
            if self.data_end is not None:
                self.summary(pos)
                break
            nxt = self.record(pos)
            if nxt is None:
                break
            pos = nxt
        self.finish()

    def frame(self, pos: int) -> tuple[int, int] | None:
        """``(opcode, length)`` of a well-framed record at ``pos``, None otherwise."""
        if pos + 9 > self.limit:
            return None
        op, length = self.f.unpack("<BQ", pos)
        if op not in _KNOWN or op == Opcode.HEADER or pos + 9 + length > self.limit:
            return None
        return op, length

    def record(self, pos: int) -> int | None:
        """Read the record at ``pos``; the position of the next one (None: the end)."""
        framed = self.frame(pos)
        if framed is None:
            return self.lost(pos, "bad record framing (unknown opcode or a length past the end of the file)")
        op, length = framed
        end = pos + 9 + length
        try:
            if op == Opcode.CHUNK:
                self.chunk(pos, length)
            elif op == Opcode.MESSAGE_INDEX:
                _check_body(self.f, pos, op, length)
                cid, n = self.f.unpack("<HI", pos + 9)
                last = self.idx.blocks[-1] if self.idx.blocks else None
                if isinstance(last, ChunkInfo):
                    last.indexed[cid] = n // 16
            elif op == Opcode.METADATA:
                m = _parse(Metadata, self.f.read(pos + 9, length))
                self.idx.metadata.append((m.name, dict(m.metadata)))
            elif op == Opcode.ATTACHMENT:
                a = _attachment(self.f.read(pos + 9, length))
                self.idx.attachments.append((a.name, a.media_type, pos, 9 + length))
            elif op == Opcode.SCHEMA:
                s = _parse(Schema, self.f.read(pos + 9, length))
                self.idx.schemas[s.id] = s
            elif op == Opcode.CHANNEL:
                c = _parse(Channel, self.f.read(pos + 9, length))
                self.idx.channels[c.id] = c
            elif op == Opcode.MESSAGE:
                _check_body(self.f, pos, op, length)
                (cid,) = self.f.unpack("<H", pos + 9)
                self.idx.blocks.append(_Loose(pos, 9 + length, cid))
            elif op == Opcode.DATA_END:
                _check_body(self.f, pos, op, length)
                self.data_end_crc(pos)
            elif op == Opcode.FOOTER:
                return None
        except _Bad as exc:
            if not self.plausible_at(end):  # the length itself is wrong: find the next record
                return self.lost(pos, str(exc))
            self.fail(_WHAT.get(op, "record"), pos, 9 + length, str(exc))
        return end

    def chunk(self, pos: int, length: int) -> None:
        try:
            start, end, *_ = _chunk_header(self.f, pos, length)
        except _Bad as exc:
            if not self.plausible_at(pos + 9 + length):
                raise
            self.idx.blocks.append(ChunkInfo(len(self.idx.chunks), pos, 9 + length, None, None, damaged=str(exc)))
            return
        info = ChunkInfo(len(self.idx.chunks), pos, 9 + length, start, end)
        self.idx.blocks.append(info)
        try:
            counts, schemas, channels = _inner_records(_decompress(self.f, pos, 9 + length))
        except _Bad as exc:
            info.damaged = str(exc)
            return
        info.counts = counts
        for s in schemas:
            self.idx.schemas[s.id] = s
        for c in channels:
            self.idx.channels[c.id] = c

    def data_end_crc(self, pos: int) -> None:
        self.data_end = pos
        self.idx.finished = True
        (crc,) = self.f.unpack("<I", pos + 9)
        if crc and self.f.crc(0, pos) != crc and not self.idx.damage and not self.damaged_chunks():
            self.fail("data section", 0, pos, "CRC mismatch although every chunk and attachment checks out: "
                      "a metadata, index or chunk-header record is damaged")

    def damaged_chunks(self) -> list[ChunkInfo]:
        return [c for c in self.idx.chunks if c.damaged is not None]

    # -- resynchronising --------------------------------------------------------------------
    def plausible_at(self, pos: int, depth: int = 0) -> bool:
        """A record (or the end of the records) starts at ``pos``."""
        if pos == self.limit:
            return True
        framed = self.frame(pos)
        if framed is None:
            return False
        op, length = framed
        try:
            _check_body(self.f, pos, op, length)
        except _Bad:
            return False
        return depth == 0 or self.plausible_at(pos + 9 + length, depth - 1)

    def resync(self, start: int) -> int | None:
        """The first position from ``start`` on where a plausible record starts (see the
        module docstring); candidates are found with numpy, 4 MiB at a time."""
        a, limit = start, self.limit
        while a + 9 <= limit:
            b = min(a + (1 << 22), limit - 8)
            window = np.frombuffer(self.f.read(a, b + 8 - a), dtype=np.uint8)
            cand = np.flatnonzero(np.isin(window[: b - a], _OPCODES))
            # a record length below 2**40: its three high bytes are zero
            keep = (window[cand + 6] == 0) & (window[cand + 7] == 0) & (window[cand + 8] == 0)
            for p in cand[keep] + a:
                if self.plausible_at(int(p), depth=1):
                    return int(p)
            a = b
        return None

    def lost(self, pos: int, reason: str) -> int | None:
        """Bytes from ``pos`` cannot be read: skip to the next plausible record."""
        nxt = self.resync(pos + 1)
        if nxt is None:
            if self.footer is None:  # never finished: the writer was killed inside this record
                self.idx.tail = (pos, self.limit - pos)
            else:
                self.fail("bytes", pos, self.limit - pos, f"{reason}; nothing readable after them")
            return None
        self.fail("bytes", pos, nxt - pos, f"{reason}; reading resumed at byte {nxt}")
        return nxt

    # -- the summary ----------------------------------------------------------------------------
    def summary(self, pos: int) -> None:
        self.summary_read = True
        if self.footer is None:
            self.fail("footer", pos, self.size - pos, "the file has a data end but no readable footer: its "
                      "summary is missing or damaged")
            return
        start, _, crc = self.footer
        f = self.limit
        if crc and self.f.crc(start, f + 25) != crc:
            self.fail("summary", start, f - start, "CRC mismatch")
            return
        while pos < f:
            framed = self.frame(pos)
            if framed is None:
                self.fail("summary", pos, f - pos, "bad record framing")
                return
            op, length = framed
            body = self.f.read(pos + 9, length)
            try:
                if op == Opcode.CHUNK_INDEX:
                    self.summary_chunks.append(_chunk_index(body))
                elif op == Opcode.CHANNEL:
                    c = _parse(Channel, body)
                    self.summary_channels[c.id] = c
                elif op == Opcode.SCHEMA:
                    s = _parse(Schema, body)
                    self.summary_schemas[s.id] = s
            except (_Bad, struct.error) as exc:
                self.fail("summary", pos, 9 + length, str(exc))
                return
            pos += 9 + length

    def finish(self) -> None:
        idx = self.idx
        if self.footer is not None and not idx.finished:
            idx.finished = True  # its data end was lost in a damaged stretch
        if self.data_end is not None and self.footer is None and not self.summary_read:
            self.fail("footer", self.limit, self.size - self.limit, "the file ends at its data end: the summary "
                      "and footer are missing")
        for cid, c in self.summary_channels.items():
            idx.channels.setdefault(cid, c)
        for sid, s in self.summary_schemas.items():
            idx.schemas.setdefault(sid, s)
        for c in idx.chunks:
            if c.damaged is None:
                for cid, n in c.counts.items():
                    idx.counts[cid] = idx.counts.get(cid, 0) + n
        for b in idx.blocks:
            if isinstance(b, _Loose):
                idx.counts[b.channel] = idx.counts.get(b.channel, 0) + 1
        described = [self.describe_chunk(c) for c in self.damaged_chunks()]
        regions = [self.describe_region(d) for d in idx.damage]
        idx.damage = sorted(described + regions, key=lambda d: d.offset)
        idx.readable = {cid for cid, ch in idx.channels.items() if not ch.schema_id or ch.schema_id in idx.schemas}
        for cid, n in sorted(idx.counts.items()):
            if cid in idx.readable:
                continue
            del idx.counts[cid]
            ch = idx.channels.get(cid)
            what = "its channel record" if ch is None else f"the schema record of {ch.topic}"
            self.fail("messages", 0, 0, f"{n} messages on channel {cid} cannot be decoded: {what} was lost")
        for cid in [c for c in idx.channels if c not in idx.readable]:
            del idx.channels[cid]

    def topics_of(self, ids: Any) -> tuple[str, ...]:
        return tuple(sorted({self.idx.channels[i].topic for i in ids if i in self.idx.channels}))

    def describe_chunk(self, c: ChunkInfo) -> Damage:
        ids: Any = c.indexed
        start, end = c.start_ns, c.end_ns
        for off, _, s, e, chans in self.summary_chunks:
            if off == c.offset:
                ids = ids or chans
                start, end = (s, e) if start is None else (start, end)
        n = sum(c.indexed.values()) if c.indexed else None
        return Damage(f"chunk {c.number}", c.offset, c.length, str(c.damaged), c.number, start, end,
                      True, self.topics_of(ids), n)

    def describe_region(self, d: Damage) -> Damage:
        """A stretch of bytes: the chunks the summary puts inside it, or its neighbours' times."""
        if d.what != "bytes":
            return d
        inside = [s for s in self.summary_chunks if d.offset <= s[0] < d.offset + d.length]
        if inside:
            chans = {i for s in inside for i in s[4]}
            return Damage(d.what, d.offset, d.length, d.reason, None, min(s[2] for s in inside),
                          max(s[3] for s in inside), True, self.topics_of(chans))
        before = [c for c in self.idx.chunks if c.offset < d.offset and c.end_ns is not None]
        after = [c for c in self.idx.chunks if c.offset > d.offset and c.start_ns is not None]
        if before or after:
            a = before[-1].end_ns if before else (after[0].start_ns if after else None)
            b = after[0].start_ns if after else before[-1].end_ns
            return Damage(d.what, d.offset, d.length, d.reason, None, a, b, False)
        return d


def _chunk_index(body: bytes) -> tuple[int, int, int, int, tuple[int, ...]]:
    """``(chunk offset, length, start, end, channel ids)`` of a chunk index record."""
    start, end, offset, length, n = struct.unpack_from("<QQQQI", body, 0)
    if n % 10 or 36 + n > len(body):
        raise _Bad("chunk index: bad message index map")
    ids = tuple(struct.unpack_from("<H", body, 36 + k)[0] for k in range(0, n, 10))
    return offset, length, start, end, ids


_WHAT = {
    Opcode.CHUNK: "chunk",
    Opcode.MESSAGE_INDEX: "message index",
    Opcode.METADATA: "metadata record",
    Opcode.ATTACHMENT: "attachment",
    Opcode.SCHEMA: "schema record",
    Opcode.CHANNEL: "channel record",
    Opcode.MESSAGE: "message record",
    Opcode.DATA_END: "data end",
}
