"""A copy of a recording with some topics left out: the base of an imported DUT output.

``bench import-nav`` (:mod:`bench.exchange.nav_import`) writes a recording that holds a
run's content -- every topic, metadata record and attachment -- with the DUT's output
topics replaced. :func:`transcribe` copies what is kept message by message (payloads,
log times, schemas and channel metadata as they are) into an open
:class:`~bench.record.writer.RecordingWriter`; the caller adds the new topics and
closes the writer with the source's ``run_end`` status.
"""

from __future__ import annotations

from collections.abc import Collection

from bench.record.reader import RecordingReader
from bench.record.writer import RecordingWriter

__all__ = ["transcribe"]


def transcribe(
    src: RecordingReader,
    dst: RecordingWriter,
    *,
    drop_topics: Collection[str] = (),
    drop_metadata: Collection[str] = ("run_end",),
) -> dict[str, int]:
    """Copy ``src`` into ``dst`` except the topics ``drop_topics`` and the metadata records
    ``drop_metadata``; returns the number of messages copied per topic (empty topics are
    declared too)."""
    schemas = {t: s for t, s in src.topic_schemas().items() if t not in drop_topics}
    for ts in schemas.values():
        dst.raw_topic(ts.topic, ts.message_encoding, ts.schema_name, ts.schema_encoding, ts.schema_data, ts.metadata)
    for name, values in src.metadata().items():
        if name not in drop_metadata:
            dst.metadata(name, values)
    for name, data in src.attachments().items():
        dst.attach(name, data, "application/octet-stream")
    counts = dict.fromkeys(schemas, 0)
    for topic, log_time, data in src.iter_raw(list(schemas)):
        dst.write_raw(topic, log_time, data)
        counts[topic] += 1
    return counts
