"""Reading the Foxglove views of a recording as Foxglove would: the mcap reader with
mcap_protobuf's DecoderFactory, every message of every /foxglove channel."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory


def decode_views(path: str | Path) -> dict[str, list[tuple[int, Any]]]:
    """Topic -> [(log time, decoded message)] of every /foxglove channel, checking that each
    is protobuf (schema and message), marked derived with its sources, and that every
    message the summary counts was decoded."""
    out: dict[str, list[tuple[int, Any]]] = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        channels = {c.id: c for c in summary.channels.values() if c.topic.startswith("/foxglove/")}
        for c in channels.values():
            schema = summary.schemas[c.schema_id]
            assert (c.message_encoding, schema.encoding) == ("protobuf", "protobuf"), c.topic
            assert c.metadata["derived"] == "true" and c.metadata["source"], c.topic
        for _, channel, message, decoded in reader.iter_decoded_messages(topics=[c.topic for c in channels.values()]):
            out.setdefault(channel.topic, []).append((message.log_time, decoded))
        for cid, c in channels.items():
            assert len(out.get(c.topic, [])) == summary.statistics.channel_message_counts[cid], c.topic
    return out


def rotate_x(q: Any) -> np.ndarray:
    """The body +x axis in the parent frame for a foxglove.Quaternion (written out, not the
    bench's rotation code)."""
    w, x, y, z = q.w, q.x, q.y, q.z
    return np.array([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)])


def bench_ns(epoch_ns: int, stamp: Any) -> int:
    """Bench time of a foxglove timestamp (UTC)."""
    return stamp.seconds * 1_000_000_000 + stamp.nanos - epoch_ns
