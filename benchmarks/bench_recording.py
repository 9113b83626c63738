"""What reading a recording costs, intact and damaged: the damage-aware scanner against the
``mcap`` library's own reader.

Synthesizes S000 (3600 s, truth at 100 Hz, 200 Hz IMU with its ideal increments) once, then
times, on one core: opening it (the scan that checks every chunk's CRC), reading ``/truth``
and ``/imu``, the library's indexed reader reading the same two topics; and the same file
with 64 bytes flipped in a chunk and cut at two thirds (killed), with what was skipped.

    .venv/bin/python benchmarks/bench_recording.py
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def main() -> None:
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    from mcap.reader import make_reader

    from bench.record.mcap_io import RecordingReader
    from bench.scenario.loader import load_scenario
    from bench.synth import SynthOptions, synthesize

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "s000.mcap"
        sc = load_scenario("S000")
        synthesize(sc, path, SynthOptions(seed=1))
        size = path.stat().st_size
        print(f"S000 synth recording: {size / 1e6:.1f} MB")

        def library() -> int:
            n = 0
            with path.open("rb") as fh:
                for _, _, msg in make_reader(fh).iter_messages(topics=["/truth", "/imu"], log_time_order=False):
                    n += len(msg.data)
            return n

        lib_bytes, t_lib = _timed(library)
        r, t_open = _timed(lambda: RecordingReader(path))
        (truth, imu), t_read = _timed(lambda: (r.read_columnar("/truth"), r.read_columnar("/imu")))
        print(f"  intact : open (scan, every chunk CRC-checked) {t_open:.3f} s; /truth + /imu {t_read:.3f} s "
              f"({len(truth)} + {len(imu)} records); mcap indexed reader, same topics: {t_lib:.3f} s "
              f"({lib_bytes / 1e6:.0f} MB of payload)")

        data = bytearray(path.read_bytes())
        mid = r._index.chunks[len(r._index.chunks) // 2]
        for k in range(mid.offset + mid.length // 2, mid.offset + mid.length // 2 + 64):
            data[k] ^= 0xFF
        flipped = Path(d) / "flipped.mcap"
        flipped.write_bytes(bytes(data))
        f, t_open = _timed(lambda: RecordingReader(flipped))
        truth_f, t_read = _timed(lambda: f.read_columnar("/truth"))
        print(f"  flipped: open {t_open:.3f} s, /truth {t_read:.3f} s: {len(truth) - len(truth_f)} truth records "
              f"lost of {len(truth)}; {f.damage_lines()[0][:110]}...")

        cut = Path(d) / "cut.mcap"
        cut.write_bytes(bytes(data[: len(data) * 2 // 3]))
        c, t_open = _timed(lambda: RecordingReader(cut))
        truth_c, t_read = _timed(lambda: c.read_columnar("/truth"))
        print(f"  killed at 2/3, flipped: open {t_open:.3f} s, /truth {t_read:.3f} s: {len(truth_c)} truth records, "
              f"finished={c.finished}, damage={len(c.damage)}, tail={c.tail[1] if c.tail else 0} B")


if __name__ == "__main__":
    main()
