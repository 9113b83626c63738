"""The receiver's time-tag error on the wire: the NMEA time fields carry the true
measurement time plus the tag error (recorded in the truth as ``stamp_ns``), separate from
the transmission latency, and nothing on the DUT's side counts such an epoch as bad."""

from __future__ import annotations

import numpy as np

from bench.record.mcap_io import RecordingReader
from bench.run.engine import run
from bench.wire.nmea_stream import NmeaStreamDecoder
from tests.run.test_engine import TABLES, _spec


def test_sentence_times_are_truth_plus_tag_error_and_arrival_is_latency(tmp_path):
    tables = {**TABLES, "bds": {"model": "seed001", "latency": "80 ms", "time_tag_error": "120 ms"}}
    spec = _spec(tmp_path / "a.mcap", duration_s=20.0)
    spec.tables = tables
    res = run(spec)
    assert res.ok, res.reason
    r = RecordingReader(res.path)
    md = r.metadata()
    assert md["dut_input_tally"] == {}  # no epoch counted late, early or bad
    bds = r.read_columnar("/bds")
    assert np.all(bds["stamp_ns"] - bds["t_ns"] == 120_000_000)
    assert np.all(bds["tx_ns"] - bds["t_ns"] == 80_000_000)
    t_g, _, buf = r.read_chunks("/wire/gnss/tx")
    can = r.read_columnar("/wire/can/tx")
    ep = can[can["can_id"] == 0x011][0]["data"][:6].astype(np.int64)
    epoch_ns = int(sum(int(b) << (8 * k) for k, b in enumerate(ep))) * 1_000_000
    fixes = NmeaStreamDecoder(epoch_utc_ns=epoch_ns).feed(buf.tobytes())
    sent = bds[bds["tx_ns"] <= 20_000_000_000]
    assert len(fixes) == len(sent) > 10
    # the sentences' time: the stamp, 120 ms after the true measurement time
    np.testing.assert_array_equal(fixes["utc_ns"] - epoch_ns, sent["stamp_ns"])
    np.testing.assert_array_equal(fixes["t_ns"], sent["t_ns"] + 120_000_000)
    # the arrival is the latency after the true time, whatever the tag says
    assert np.all(t_g % 1_000_000_000 == 80_000_000)

