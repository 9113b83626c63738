"""Offset and scale of values inside NMEA sentences on the gnss line."""

import math

import numpy as np
import pynmea2
import pytest

from bench.errors import ConfigError
from bench.faults.schedule import parse_schedule
from bench.faults.wire import WireFaultInjector
from bench.faults.wire_nmea import edit_sentence
from bench.wire.nmea import GNSS_FIX_DTYPE, encode_epochs
from bench.wire.nmea_stream import NmeaStreamDecoder

EPOCH = 1_748_736_000 * 10**9


def _fixes(n=5):
    f = np.zeros(n, GNSS_FIX_DTYPE)
    f["t_ns"] = np.arange(n) * 1_000_000_000
    f["utc_ns"] = EPOCH + f["t_ns"]
    f["lat"], f["lon"], f["h"] = math.radians(-0.00001), math.radians(108.9), 380.25
    f["vel_n"] = [3.0, 4.0, 0.0]
    f[["sigma_lat", "sigma_lon", "sigma_alt"]] = (1.5, 1.2, 2.5)
    f["sats"], f["hdop"], f["quality"] = 12, 0.9, 1
    return f


def _decode(batch):
    d = NmeaStreamDecoder(epoch_utc_ns=EPOCH)
    out = np.concatenate([d.feed(c.data) for c in batch.chunks()])
    return out, d.tally.as_dict()


@pytest.mark.parametrize(("kind", "signal", "param"), [("offset", "h", 12.5), ("scale", "speed", 2.0),
                                                       ("offset", "lat", math.radians(0.0002)),
                                                       ("scale", "sigma_alt", 3.0)])
def test_edited_sentences_stay_valid_and_carry_the_new_value(kind, signal, param):
    sched = parse_schedule([{"layer": "wire", "target": "serial:gnss", "kind": kind, "start": "1 s", "end": "3 s",
                             "params": {"signal": signal, ("value" if kind == "offset" else "factor"): param}}])
    clean = encode_epochs(_fixes())
    faulted, events = WireFaultInjector(sched, 1).serial("gnss", clean)
    for c in faulted.chunks():
        pynmea2.parse(c.data.decode().strip(), check=True)  # checksums valid
    a, tally_a = _decode(clean)
    b, tally_b = _decode(faulted)
    assert tally_b == tally_a == {}
    inside = (a["t_ns"] >= 1e9) & (a["t_ns"] < 3e9)
    field = {"h": "h", "lat": "lat", "sigma_alt": "sigma_alt"}.get(signal)
    if signal == "speed":
        sa, sb = np.hypot(*a["vel_n"][:, :2].T), np.hypot(*b["vel_n"][:, :2].T)
        assert sb[inside] == pytest.approx(sa[inside] * 2.0, abs=2e-3)
        assert np.array_equal(sb[~inside], sa[~inside])
    elif kind == "offset":
        assert b[field][inside] - a[field][inside] == pytest.approx(param, abs=1e-7 if field == "lat" else 1e-3)
        assert np.array_equal(b[field][~inside], a[field][~inside])
    else:
        assert b[field][inside] == pytest.approx(a[field][inside] * param, abs=0.01)
    assert len(events) > 0


def test_a_coordinate_crossing_the_equator_flips_its_hemisphere():
    line = encode_epochs(_fixes(1)).chunks()[1].data  # GGA at 0.00001 deg S
    out = edit_sentence(line, "lat", lambda v: v + math.radians(0.0001))
    msg = pynmea2.parse(out.decode().strip(), check=True)
    assert msg.lat_dir == "N" and msg.latitude == pytest.approx(0.00009, abs=1e-7)


def test_unknown_nmea_signal_is_refused():
    from bench.faults.wire_kinds import wire_windows

    sched = parse_schedule([{"layer": "wire", "target": "serial:gnss", "kind": "offset", "start": 0, "end": 1,
                             "params": {"signal": "altitude", "value": 1.0}}])
    with pytest.raises(ConfigError, match="signal must be one of"):
        wire_windows(sched)
