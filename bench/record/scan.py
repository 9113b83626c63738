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

import struct
from io import BytesIO
from pathlib import Path
from typing import Any

import numpy as np
from mcap.data_stream import ReadDataStream
from mcap.opcode import Opcode
from mcap.records import Channel, Metadata, Schema

from bench.errors import ConfigError
from bench.record.framing import (
    BadRecord,
    RecordFile,
    attachment_record,
    check_body,
    chunk_header,
    chunk_index,
    decompress,
    inner_records,
    open_recording,
    parse_record,
)
from bench.record.index import ChunkInfo, Damage, FileIndex, Loose
from bench.record.layout import MAGIC, PROFILE

__all__ = ["Damage", "ChunkInfo", "FileIndex", "scan"]

_OPCODES = np.array(sorted(int(o) for o in Opcode), dtype=np.uint8)
_KNOWN = frozenset(int(o) for o in Opcode)


def scan(path: str | Path) -> FileIndex:
    """Scan a bench recording (see the module docstring).

    Raises
    ------
    ConfigError
        The path is not a regular file, is empty, is not an MCAP file, or is an MCAP file of
        another profile (another program's): it says what it found.
    """
    path = Path(path)
    f = open_recording(path)
    idx = FileIndex(path, f.size, _file=f)
    try:
        _Scanner(idx, f).run()
    except BaseException:
        idx.close()
        raise
    return idx


class _Scanner:
    def __init__(self, idx: FileIndex, f: RecordFile):
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
                check_body(self.f, pos, op, length)
                cid, n = self.f.unpack("<HI", pos + 9)
                last = self.idx.blocks[-1] if self.idx.blocks else None
                if isinstance(last, ChunkInfo):
                    last.indexed[cid] = n // 16
            elif op == Opcode.METADATA:
                m = parse_record(Metadata, self.f.read(pos + 9, length))
                self.idx.metadata.append((m.name, dict(m.metadata)))
            elif op == Opcode.ATTACHMENT:
                a = attachment_record(self.f.read(pos + 9, length))
                self.idx.attachments.append((a.name, a.media_type, pos, 9 + length))
            elif op == Opcode.SCHEMA:
                s = parse_record(Schema, self.f.read(pos + 9, length))
                self.idx.schemas[s.id] = s
            elif op == Opcode.CHANNEL:
                c = parse_record(Channel, self.f.read(pos + 9, length))
                self.idx.channels[c.id] = c
            elif op == Opcode.MESSAGE:
                check_body(self.f, pos, op, length)
                (cid,) = self.f.unpack("<H", pos + 9)
                self.idx.blocks.append(Loose(pos, 9 + length, cid))
            elif op == Opcode.DATA_END:
                check_body(self.f, pos, op, length)
                self.data_end_crc(pos)
            elif op == Opcode.FOOTER:
                return None
        except BadRecord as exc:
            if not self.plausible_at(end):  # the length itself is wrong: find the next record
                return self.lost(pos, str(exc))
            self.fail(_WHAT.get(op, "record"), pos, 9 + length, str(exc))
        return end

    def chunk(self, pos: int, length: int) -> None:
        try:
            start, end, *_ = chunk_header(self.f, pos, length)
        except BadRecord as exc:
            if not self.plausible_at(pos + 9 + length):
                raise
            self.idx.blocks.append(ChunkInfo(len(self.idx.chunks), pos, 9 + length, None, None, damaged=str(exc)))
            return
        info = ChunkInfo(len(self.idx.chunks), pos, 9 + length, start, end)
        self.idx.blocks.append(info)
        try:
            counts, schemas, channels = inner_records(decompress(self.f, pos, 9 + length))
        except BadRecord as exc:
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
            check_body(self.f, pos, op, length)
        except BadRecord:
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
                    self.summary_chunks.append(chunk_index(body))
                elif op == Opcode.CHANNEL:
                    c = parse_record(Channel, body)
                    self.summary_channels[c.id] = c
                elif op == Opcode.SCHEMA:
                    s = parse_record(Schema, body)
                    self.summary_schemas[s.id] = s
            except (BadRecord, struct.error) as exc:
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
            if isinstance(b, Loose):
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
