"""Writing the Foxglove views into a recording: at the end of a run, or into a copy.

:func:`add_views` is called by every producer of recordings (the run engine for live runs
and replays, ``bench synth``, the synthetic runner) just before the recording is closed:
it flushes the writer, reads the recording back as it stands (the columnar topics are
its source of truth), derives the views (:func:`~bench.scoring.views.derive_views`) and
writes them into the same file. :func:`copy_with_views` writes a copy of a finished
recording with fresh views (``bench views``), for recordings made before them.
"""

from __future__ import annotations

from pathlib import Path

from bench.errors import ConfigError
from bench.record.copy import copy_records
from bench.record.foxglove import write_views
from bench.record.mcap_io import RecordingReader, RecordingWriter
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
                    overwrite: bool = False) -> int:
    """Write a copy of the finished recording ``src`` to ``out`` with its views (the
    source's own views, and the JSON ones of older recordings, replaced); returns the
    number of view messages.

    Raises
    ------
    ConfigError
        ``src`` is not a finished, undamaged bench recording with a ``run_end`` record;
        ``out`` is ``src`` or cannot be written (exists without ``overwrite``...).
    """
    src, out = Path(src), Path(out)
    if out.exists() and out.resolve() == src.resolve():
        raise ConfigError("expected an output other than the recording itself", file=str(out))
    with RecordingReader(src) as reader:
        if not reader.intact or "run_end" not in reader.metadata():
            what = "damaged" if reader.damage else "unfinished" if not reader.finished else "without run_end"
            raise ConfigError(f"expected a finished, undamaged recording, found one {what}", file=str(src))
        with RecordingWriter(out, epoch_ns=reader.epoch_ns(), overwrite=overwrite) as rec:
            end = copy_records(reader, rec, keep=lambda t, n, e: not is_view(t, n, e))
            n = _write(rec, reader, rate_hz)
            rec.close(end.get("status", "complete"), end.get("reason", ""))
    return n

