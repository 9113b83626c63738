"""A copy of a recording, record for record, into a new writer (``bench views``, ``bench
import-nav``).

Every readable message is written again in file order with its log time, on a channel of
the same topic, message encoding, metadata and schema (name, encoding and data as they
were); the metadata records in their order (``run_end`` is left to the writer's close)
and the attachments with their media types. Channels the caller drops (``keep``) are left
out. The copy's message times, per-topic order and contents are those of the source, so
whatever is computed from the source's topics is computed the same from the copy.
"""

from __future__ import annotations

from collections.abc import Callable, Collection

from bench.record.reader import RecordingReader
from bench.record.writer import RecordingWriter

__all__ = ["copy_records"]


def copy_records(
    src: RecordingReader,
    dst: RecordingWriter,
    keep: Callable[[str, str, str], bool] | None = None,
    *,
    drop_metadata: Collection[str] = (),
) -> dict[str, str]:
    """Copy ``src`` into ``dst`` (see the module docstring); ``keep(topic, schema name,
    schema encoding)`` says which channels to copy (all by default), ``drop_metadata`` the
    metadata records not to copy (``run_end`` never is). Returns the source's ``run_end``
    metadata (empty if it has none) for the caller to close ``dst`` with."""
    idx = src._index
    copied: set[int] = set()
    for cid, ch in sorted(idx.channels.items()):
        sch = idx.schemas.get(ch.schema_id)
        name, enc, data = (sch.name, sch.encoding, bytes(sch.data)) if sch is not None else ("", "", b"")
        if keep is not None and not keep(ch.topic, name, enc):
            continue
        dst.encoded_topic(ch.topic, name, enc, data, ch.message_encoding, dict(ch.metadata))
        copied.add(cid)
    epoch = dst.epoch_ns
    for cid, log_time, data in idx.messages(copied):
        dst.write_encoded_many(idx.channels[cid].topic, [log_time - epoch], [bytes(data)])
    run_end: dict[str, str] = {}
    for name, values in idx.metadata:
        if name == "run_end":
            run_end = dict(values)
            continue
        if name in drop_metadata:
            continue
        dst.metadata(name, dict(values))
    for name, media, off, n in idx.attachments:
        dst.attach(name, idx.attachment_data(off, n), media)
    return run_end
