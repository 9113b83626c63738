"""MCAP recordings: the bench's recording format, writer and reader.

Two kinds of topics:

* **columnar** topics carry blocks of samples as little-endian numpy structured arrays
  (schema and message encoding ``bench.columnar.v1``). The schema is JSON naming the
  fields, their types, shapes, units and frames, so any reader can decode a block with
  ``numpy.frombuffer(data, dtype)``; every record carries its own ``t_ns``. This is how
  every sample of a run fits in the file at the rates a bench runs at.
* **json** topics carry one JSON document per message (``jsonschema`` schemas), used for
  sparse events (fault windows, segments, commands, bad frames, DUT log lines).

The Foxglove views (``/foxglove/...``: map, poses, transforms, log, plots) are protobuf
channels derived from these topics when a recording is finished
(:mod:`bench.record.foxglove`, :mod:`bench.scoring.viewwrite`).

Message log times are UTC nanoseconds: the run's epoch (UTC of bench time zero) plus the
bench time of the first record in the message. Recordings are zstd-chunked with CRCs.

The ``mcap`` library is used inside :mod:`bench.record` only: :mod:`~bench.record.writer`
(writing, one locked writer per file), :mod:`~bench.record.scan` (reading record by
record past damage, with :mod:`~bench.record.framing` for the records and
:mod:`~bench.record.index` for what was found) and :mod:`~bench.record.reader` on top. This module gathers
their public names. See ``docs/recording.md`` for the topic list and the damage rules.
"""

from __future__ import annotations

from bench.record.layout import CHUNKS, COLUMNAR, PROFILE, TopicInfo, dtype_from_json, dtype_to_json
from bench.record.reader import RecordingReader
from bench.record.scan import Damage
from bench.record.writer import RecordingWriter

__all__ = [
    "COLUMNAR",
    "CHUNKS",
    "PROFILE",
    "RecordingWriter",
    "RecordingReader",
    "TopicInfo",
    "Damage",
    "dtype_to_json",
    "dtype_from_json",
]
