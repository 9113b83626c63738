"""MCAP records read one at a time from a file, each bounded by its own length.

The pieces :mod:`bench.record.scan` is built of: positioned reads that fail cleanly at the
end of a file (:class:`RecordFile`), the bodies of the records (parsed by the ``mcap``
library's readers on a buffer of exactly the record's length, so a bad record never
reads into the next), chunk headers and their decompression with the CRC check
(``get_chunk_data_stream``), and the cheap plausibility test used to resynchronise.
Every failure is :class:`BadRecord`, which never leaves :mod:`bench.record`.
"""

from __future__ import annotations

import os
import stat
import struct
import zlib
from collections.abc import Iterator
from io import BytesIO
from pathlib import Path
from typing import Any

from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel, Chunk, Metadata, Schema
from mcap.stream_reader import get_chunk_data_stream

from bench.errors import ConfigError
from bench.record.layout import MAGIC

__all__ = [
    "BadRecord",
    "RecordFile",
    "chunk_header",
    "decompress",
    "inner_messages",
    "inner_records",
    "parse_record",
    "check_body",
    "attachment_record",
    "chunk_index",
    "open_recording",
]

_MAX_UNCOMPRESSED = 1 << 30  # a chunk header claiming more is damaged


class BadRecord(Exception):  # noqa: N818 - internal to bench.record
    """A record body that does not parse (the reason is the message)."""


class RecordFile:
    """Positioned reads of an open file (a short read past a truncation raises BadRecord)."""

    def __init__(self, fh: Any, size: int):
        self.fh = fh
        self.fd = fh.fileno()
        self.size = size

    def read(self, pos: int, n: int) -> bytes:
        out = os.pread(self.fd, n, pos) if n > 0 else b""
        if len(out) != max(n, 0):
            raise BadRecord(f"the file ends at byte {pos + len(out)}, inside a record")
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
def chunk_header(f: RecordFile, pos: int, length: int) -> tuple[int, int, int, int, str, int, int]:
    """``(start, end, uncompressed size, crc, compression, data offset, data length)`` of the
    chunk record at ``pos`` (its body is ``length`` bytes)."""
    body = pos + 9
    if length < 40:
        raise BadRecord("chunk record too short")
    head = f.read(body, min(length, 48))
    start, end, usize, crc, clen = struct.unpack_from("<QQQII", head, 0)
    if clen > 8 or 32 + clen + 8 > length:
        raise BadRecord(f"bad compression field length {clen}")
    try:
        comp = head[32 : 32 + clen].decode("ascii")
    except UnicodeDecodeError:
        raise BadRecord("compression name is not ASCII") from None
    if comp not in ("", "zstd", "lz4"):
        raise BadRecord(f"unknown compression {comp!r}")
    (dlen,) = struct.unpack_from("<Q", head, 32 + clen)
    data = body + 32 + clen + 8
    if data + dlen > body + length:
        raise BadRecord(f"chunk data of {dlen} B runs past its record ({length} B)")
    if usize > _MAX_UNCOMPRESSED or start > end:
        raise BadRecord(f"implausible chunk header (uncompressed {usize} B, times {start}..{end})")
    return start, end, usize, crc, comp, data, dlen


def decompress(f: RecordFile, pos: int, length: int) -> bytes:
    """The uncompressed records of the chunk record at ``pos``, CRC checked (or BadRecord)."""
    start, end, usize, crc, comp, data, dlen = chunk_header(f, pos, length - 9)
    chunk = Chunk(compression=comp, data=f.read(data, dlen), message_end_time=end,
                  message_start_time=start, uncompressed_crc=crc, uncompressed_size=usize)
    try:
        stream, n = get_chunk_data_stream(chunk, validate_crc=True)
        out = stream.read(n) if n else b""
    except Exception as exc:  # CRC mismatch, a broken zstd/lz4 frame, a missing codec
        raise BadRecord(_reason(exc)) from None
    if len(out) != usize:
        raise BadRecord(f"decompressed to {len(out)} B, the header says {usize} B")
    return out


def _reason(exc: BaseException) -> str:
    text = str(exc) or type(exc).__name__
    if "crc" in text.lower():
        return f"CRC mismatch ({text})"
    return f"cannot be decompressed ({type(exc).__name__}: {text})"


def inner_messages(data: bytes) -> Iterator[tuple[int, int, int, int]]:
    """``(channel id, log time, data start, data end)`` of the message records in
    uncompressed chunk records (already validated by :func:`inner_records`)."""
    pos, n = 0, len(data)
    while pos < n:
        op = data[pos]
        (length,) = struct.unpack_from("<Q", data, pos + 1)
        if op == Opcode.MESSAGE:
            cid, _, log_time, _ = struct.unpack_from("<HIQQ", data, pos + 9)
            yield cid, log_time, pos + 9 + 22, pos + 9 + length
        pos += 9 + length


def inner_records(data: bytes) -> tuple[dict[int, int], list[Schema], list[Channel]]:
    """Messages per channel, schemas and channels of uncompressed chunk records (or BadRecord)."""
    counts: dict[int, int] = {}
    schemas: list[Schema] = []
    channels: list[Channel] = []
    pos, n = 0, len(data)
    while pos < n:
        if pos + 9 > n:
            raise BadRecord("a record inside the chunk is cut short")
        op = data[pos]
        (length,) = struct.unpack_from("<Q", data, pos + 1)
        if pos + 9 + length > n:
            raise BadRecord(f"a record inside the chunk claims {length} B past the chunk's end")
        if op == Opcode.MESSAGE:
            if length < 22:
                raise BadRecord("a message record inside the chunk is too short")
            (cid,) = struct.unpack_from("<H", data, pos + 9)
            counts[cid] = counts.get(cid, 0) + 1
        elif op == Opcode.SCHEMA:
            schemas.append(parse_record(Schema, data[pos + 9 : pos + 9 + length]))
        elif op == Opcode.CHANNEL:
            channels.append(parse_record(Channel, data[pos + 9 : pos + 9 + length]))
        pos += 9 + length
    return counts, schemas, channels


def parse_record(kind: Any, body: bytes) -> Any:
    """A record body parsed by the library's reader, bounded by its length (or BadRecord)."""
    try:
        return kind.read(ReadDataStream(BytesIO(body)))
    except Exception as exc:  # the library raises EndOfFile, struct.error, UnicodeDecodeError...
        raise BadRecord(f"{kind.__name__} record does not parse ({type(exc).__name__})") from None


def check_body(f: RecordFile, pos: int, op: int, length: int) -> None:
    """Cheap plausibility of a record body (used to resynchronise); raises BadRecord."""
    if op == Opcode.CHUNK:
        chunk_header(f, pos, length)
        return
    body = f.read(pos + 9, length) if op != Opcode.MESSAGE else f.read(pos + 9, min(length, 22))
    if op == Opcode.MESSAGE_INDEX:
        if length < 6:
            raise BadRecord("message index too short")
        _, n = struct.unpack_from("<HI", body, 0)
        if n % 16 or 6 + n > length:
            raise BadRecord("message index length")
    elif op == Opcode.DATA_END:
        if length != 4:
            raise BadRecord("data end length")
    elif op == Opcode.FOOTER:
        if length != 20:
            raise BadRecord("footer length")
    elif op == Opcode.METADATA:
        parse_record(Metadata, body)
    elif op == Opcode.ATTACHMENT:
        attachment_record(body)
    elif op == Opcode.SCHEMA:
        parse_record(Schema, body)
    elif op == Opcode.CHANNEL:
        parse_record(Channel, body)
    elif op == Opcode.MESSAGE and length < 22:
        raise BadRecord("message too short")


def attachment_record(body: bytes) -> Attachment:
    rec = parse_record(Attachment, body)
    (crc,) = struct.unpack_from("<I", body, len(body) - 4)
    if crc and zlib.crc32(body[:-4]) != crc:
        raise BadRecord(f"attachment {rec.name!r}: CRC mismatch")
    return rec


# -- the scan ----------------------------------------------------------------------------------
def preview(head: bytes) -> str:
    if all(32 <= c < 127 for c in head):
        return repr(head.decode("ascii"))
    return "bytes " + head.hex(" ")


def open_recording(path: Path) -> RecordFile:
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
        fh = open(path, "rb")  # noqa: SIM115 - owned by the returned RecordFile
    except OSError as exc:
        raise ConfigError(f"cannot read it: {exc.strerror or exc}", file=str(path)) from None
    try:
        head = fh.read(8)
    except OSError as exc:
        fh.close()
        raise ConfigError(f"cannot read it: {exc.strerror or exc}", file=str(path)) from None
    if head != MAGIC:
        fh.close()
        raise ConfigError(f"starts with {preview(head)}, not the MCAP magic: not a recording", file=str(path))
    return RecordFile(fh, st.st_size)


def chunk_index(body: bytes) -> tuple[int, int, int, int, tuple[int, ...]]:
    """``(chunk offset, length, start, end, channel ids)`` of a chunk index record."""
    start, end, offset, length, n = struct.unpack_from("<QQQQI", body, 0)
    if n % 10 or 36 + n > len(body):
        raise BadRecord("chunk index: bad message index map")
    ids = tuple(struct.unpack_from("<H", body, 36 + k)[0] for k in range(0, n, 10))
    return offset, length, start, end, ids
