"""BDS receiver: per-axis sizing (white + Gauss-Markov), the seed's measured sets, time-tag error."""

from __future__ import annotations

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.faults.schedule import FaultSchedule
from bench.run.traffic import TrafficEncoder
from bench.sensors.bds import BDS_PARAMS, BdsReceiver, sigmas, split_sigmas
from bench.sensors.params import resolve
from bench.wire.nmea_stream import NmeaStreamDecoder
from tests.sensors.helpers import StaticTrajectory, run_all

EPOCH = 1_700_000_000 * 10**9
MS = 1_000_000


def params(**table):
    return resolve("bds", table, BDS_PARAMS)


def test_per_axis_sigmas_override_the_95_figures_and_gst_is_the_total():
    p = params(white_sigma=["0.3 m", "0.4 m", "1 m"], markov_sigma=["0.4 m", "0.3 m", "0 m"], velocity_white_sigma=0.1)
    pos, vel = sigmas(p)
    assert np.allclose(pos, [0.5, 0.5, 1.0])
    assert np.allclose(vel, [0.1, 0.1, 0.1])
    s = split_sigmas(p)
    assert np.allclose(s["vel_markov"], 0.0)


@pytest.mark.parametrize(
    ("model", "rms"),
    [("seed001_driving", [0.619, 2.759, 2.437]), ("seed001_static", [0.787, 1.460, 2.288])],
)
def test_seed_sets_reproduce_the_seed_rms_and_report_it(model, rms):
    p = params(model=model)
    assert np.allclose(sigmas(p)[0], rms, rtol=2e-3)
    m = BdsReceiver(p, seed=3)
    rec = run_all(m, StaticTrajectory(duration_s=20000.0), window_s=500.0)
    err = rec["error_enu"]
    # 20000 s over a 30-120 s correlation time: sample RMS within ~10 %
    assert np.allclose(np.sqrt(np.mean(err**2, axis=0)), rms, rtol=0.12)
    assert np.allclose(rec["sigma_lon"], rms[0], rtol=2e-3)
    assert np.allclose(rec["sigma_lat"], rms[1], rtol=2e-3)
    assert np.allclose(rec["sigma_alt"], rms[2], rtol=2e-3)


def test_mixing_both_sizings_is_refused_naming_the_key():
    with pytest.raises(ConfigError, match="vertical_95"):
        BdsReceiver(params(model="seed001_driving", vertical_95="5 m"), seed=0)
    with pytest.raises(ConfigError, match="white_sigma"):
        BdsReceiver(params(white_sigma=["1 m", "-1 m", "1 m"]), seed=0)


def test_service_figure_set_unchanged():
    pos, vel = sigmas(params(model="seed001"))
    assert np.allclose(pos, [10 / 2.4477, 10 / 2.4477, 10 / 1.96], rtol=1e-3)
    assert np.allclose(vel, [0.2 / 2.4477, 0.2 / 2.4477, 0.2 / 1.96], rtol=1e-3)


def _wire_times(m, rec):
    enc = TrafficEncoder([m], epoch_ns=EPOCH, lockstep=True, schedule=FaultSchedule(), seed=0)
    gnss = enc._gnss(rec, int(rec["tx_ns"].max()))
    dec = NmeaStreamDecoder(epoch_utc_ns=EPOCH, late_ns=100 * MS)
    fixes = np.concatenate([dec.feed_batch(gnss), dec.flush()])
    return fixes, dec


@pytest.mark.parametrize(("tag", "drift"), [("80 ms", 0.0), ("-30 ms", 0.0), ("20 ms", 1e-4)])
def test_time_tag_error_on_the_wire(tag, drift):
    m = BdsReceiver(params(time_tag_error=tag, time_tag_drift=drift, latency="80 ms"), seed=1)
    rec = run_all(m, StaticTrajectory(duration_s=600.0), window_s=60.0)
    # the true measurement times are untouched
    assert np.array_equal(rec["t_ns"], np.arange(1, 601) * 10**9)
    tag_s = float(tag.split()[0]) * 1e-3
    expected = rec["t_ns"] + np.rint((tag_s * 1e9 + drift * rec["t_ns"]) / 1e7).astype(np.int64) * 10_000_000
    assert np.array_equal(rec["stamp_ns"], expected)
    assert np.all(rec["stamp_ns"] % (10 * MS) == 0)
    fixes, dec = _wire_times(m, rec)
    assert np.array_equal(fixes["utc_ns"] - EPOCH, rec["stamp_ns"])
    # no bad bytes; a stamp later than the truth (even at the arrival) is not late; one
    # earlier than the truth makes the epoch look older by the tag (late past 100 ms here)
    assert dec.bytes_bad == 0
    late = dec.tally.as_dict().get("late", 0)
    assert late == (len(rec) if tag_s < 0 else 0)
    if drift:
        assert rec["stamp_ns"][-1] - rec["t_ns"][-1] == 80 * MS  # 20 ms + 1e-4 * 600 s
