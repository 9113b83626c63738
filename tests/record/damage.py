"""Damaged copies of a recording, as the tests of damage and replay make them."""

from __future__ import annotations

import shutil
from pathlib import Path

from bench.record.scan import scan


def killed(src: Path, dst: Path) -> Path:
    """What SIGKILL two thirds into the run leaves (no summary, no footer, and none of the
    Foxglove views, which a finished run writes at its end)."""
    data = src.read_bytes()
    idx = scan(src)
    views = {cid for cid, ch in idx.channels.items() if ch.topic.startswith("/foxglove/")}
    end = min((c.offset for c in idx.chunks if views.intersection(c.counts)), default=len(data))
    idx.close()
    dst.write_bytes(data[: end * 2 // 3])
    return dst


def footer_damaged(src: Path, dst: Path) -> Path:
    """The footer's summary offsets zeroed."""
    data = bytearray(src.read_bytes())
    data[-37:-29] = b"\0" * 8
    dst.write_bytes(bytes(data))
    return dst


def chunk_flipped(src: Path, dst: Path) -> Path:
    """64 bytes flipped in the middle of the middle chunk."""
    shutil.copy(src, dst)
    idx = scan(dst)
    c = idx.chunks[len(idx.chunks) // 2]
    idx.close()
    data = bytearray(dst.read_bytes())
    for k in range(c.offset + c.length // 2, c.offset + c.length // 2 + 64):
        data[k] ^= 0xFF
    dst.write_bytes(bytes(data))
    return dst
