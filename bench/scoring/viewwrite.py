"""Writing the Foxglove views into a recording: at the end of a run, or into a copy.

:func:`add_views` is called by every producer of recordings (the run engine for live runs
and replays, ``bench synth``, the synthetic runner) just before the recording is closed:
it flushes the writer, reads the recording back as it stands (the columnar topics are
its source of truth), derives the views (:func:`~bench.scoring.views.derive_views`) and
writes them into the same file. :func:`copy_with_views` writes a copy of a recording with
fresh views (``bench views``), for recordings made before them or cut short before the end
of their run wrote them.
"""

from __future__ import annotations

from pathlib import Path

from bench.errors import ConfigError
from bench.record.copy import copy_records
from bench.record.foxglove import write_views
from bench.record.mcap_io import RecordingReader, RecordingWriter
from bench.record.provenance import copy_metadata
from bench.scoring.data import read_run
from bench.scoring.views import DEFAULT_RATE_HZ, LOG, derive_views

__all__ = ["add_views", "copy_with_views", "is_view"]

#: the views' topic prefix
PREFIX = "/foxglove/"
#: the JSON Foxglove topics of recordings made before the protobuf views (not copied)
_OLD_VIEWS = {"foxglove.LocationFix", "foxglove.PoseInFrame"}


def is_view(topic: str, schema_name: str, schema_encoding: str) -> bool:
    """A derived view (this one's, or the JSON views of older recordings)."""
    return topic.startswith(PREFIX) or (schema_encoding == "jsonschema" and schema_name in _OLD_VIEWS)


def _write(rec: RecordingWriter, reader: RecordingReader, rate_hz: float) -> int:
    run = read_run(reader)
    log = [doc for _, doc in reader.iter_json(LOG)] if LOG in reader.topics() else []
    return write_views(rec, derive_views(run, log, rate_hz), {"rate_hz": f"{rate_hz:g}"})


def add_views(rec: RecordingWriter, rate_hz: float = DEFAULT_RATE_HZ) -> int:
    """Write the views of the recording ``rec`` is writing into it (before it is closed);
    returns the number of view messages. Nothing is written once the writer failed."""
    if rec.failed:
        return 0
    rec.flush()
    with RecordingReader(rec.path) as reader:
        return _write(rec, reader, rate_hz)


def copy_with_views(src: str | Path, out: str | Path, *, rate_hz: float = DEFAULT_RATE_HZ,
                    overwrite: bool = False, accept_damaged_source: bool = False) -> tuple[int, dict[str, str]]:
    """Write a copy of the recording ``src`` to ``out`` with its views (the source's own
    views, and the JSON ones of older recordings, replaced); returns the number of view
    messages and the source's state as the copy's ``run_start`` records it
    (:func:`bench.record.provenance.copy_metadata`: none for a sound source).

    A ``src`` that is unfinished, damaged, without ``run_end`` or itself made from such a
    recording is copied as far as it can be read; its state travels into the copy, which
    ``bench score`` judges ERROR unless ``accept_damaged_source`` (then with a note). The
    copy keeps the source's ``run_end`` (``complete`` if it has none: its problems say so).

    Raises
    ------
    ConfigError
        ``out`` is ``src`` or cannot be written (exists without ``overwrite``...).
    """
    src, out = Path(src), Path(out)
    if out.exists() and out.resolve() == src.resolve():
        raise ConfigError("expected an output other than the recording itself", file=str(out))
    with RecordingReader(src) as reader:
        provenance = copy_metadata(reader, accepted=accept_damaged_source, made_by="views")
        with RecordingWriter(out, epoch_ns=reader.epoch_ns(), overwrite=overwrite) as rec:
            end = copy_records(reader, rec, keep=lambda t, n, e: not is_view(t, n, e),
                               drop_metadata=("run_start",) if provenance else ())
            if provenance:
                rec.metadata("run_start", {**reader.metadata().get("run_start", {}), **provenance})
            n = _write(rec, reader, rate_hz)
            rec.close(end.get("status", "complete"),
                      end.get("reason", "") if end else f"{src.name} has no run_end (see run_start.source_problems)")
    return n, provenance
