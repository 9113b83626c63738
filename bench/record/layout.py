"""What a bench recording looks like: encodings, the profile, topic descriptions.

Shared by the writer (:mod:`bench.record.writer`), the reader
(:mod:`bench.record.reader`) and the scanner (:mod:`bench.record.scan`); no library
import here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["COLUMNAR", "CHUNKS", "PROFILE", "MAGIC", "TopicInfo", "dtype_to_json", "dtype_from_json"]

#: Schema and message encoding of columnar blocks.
COLUMNAR = "bench.columnar.v1"
#: Schema and message encoding of byte chunks (serial traffic): ``u4 n``, then ``n``
#: little-endian ``i8`` times, ``n`` ``u4`` lengths, then the bytes of the chunks.
CHUNKS = "bench.chunks.v1"
#: The MCAP profile of every bench recording (the header record says it).
PROFILE = "nav-hil-bench"
#: The 8 bytes an MCAP file starts and ends with.
MAGIC = b"\x89MCAP0\r\n"


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
    """What a topic holds (``messages``: those that could be read)."""

    topic: str
    schema: str
    encoding: str
    messages: int
    metadata: dict[str, str]
