"""NMEA sentences: pynmea2 as the independent parser, round trips through the stream decoder."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pynmea2
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.errors import CodecError
from bench.wire.nmea import GNSS_FIX_DTYPE, MAX_SENTENCE, SENTENCES, checksum, encode_epochs
from bench.wire.nmea_fields import parse_sentence
from bench.wire.nmea_stream import NmeaStreamDecoder

EPOCH_UTC = 1_748_736_000 * 10**9  # 2025-06-01T00:00:00Z
KNOT = 1852.0 / 3600.0  # m/s, the international knot

FIX = st.fixed_dictionaries(
    {
        "utc_s": st.integers(0, 4_102_444_799),  # 1970 .. 2099
        "cs": st.integers(0, 99),
        "lat": st.floats(-90.0, 90.0),
        "lon": st.floats(-180.0, 180.0),
        "h": st.floats(-999.0, 99_999.0),
        "ve": st.floats(-300.0, 300.0),
        "vn": st.floats(-300.0, 300.0),
        "s": st.tuples(st.floats(0, 999), st.floats(0, 999), st.floats(0, 999)),
        "sats": st.integers(0, 99),
        "hdop": st.floats(0, 99.9),
        "quality": st.sampled_from([0, 1, 2, 4, 5, 6]),
    }
)


def _fixes(items) -> np.ndarray:
    f = np.zeros(len(items), GNSS_FIX_DTYPE)
    for i, d in enumerate(items):
        f[i]["utc_ns"] = d["utc_s"] * 10**9 + d["cs"] * 10**7
        f[i]["t_ns"] = f[i]["utc_ns"] - EPOCH_UTC
        f[i]["lat"], f[i]["lon"], f[i]["h"] = math.radians(d["lat"]), math.radians(d["lon"]), d["h"]
        f[i]["vel_n"] = (d["ve"], d["vn"], 0.0)
        f[i]["sigma_lat"], f[i]["sigma_lon"], f[i]["sigma_alt"] = d["s"]
        f[i]["sats"], f[i]["hdop"], f[i]["quality"] = d["sats"], d["hdop"], d["quality"]
    return f


def _steady_fixes(n: int) -> np.ndarray:
    """``n`` fixes one second apart, all with the same position, velocity and accuracy."""
    common = {"cs": 0, "lat": 34.2, "lon": 108.9, "h": 380.0, "ve": 1.0, "vn": 2.0, "s": (1.0, 2.0, 3.0), "sats": 12,
              "hdop": 0.9, "quality": 1}
    return _fixes([{"utc_s": 1_748_736_000 + k, **common} for k in range(n)])


@settings(max_examples=150, deadline=None)
@given(st.lists(FIX, min_size=1, max_size=4), st.sampled_from(["GB", "BD", "GN"]))
def test_pynmea2_parses_every_sentence_to_the_values_meant(items, talker):
    fixes = _fixes(items)
    batch = encode_epochs(fixes, talker=talker)
    assert len(batch) == 5 * len(items)
    for i, chunk in enumerate(batch.chunks()):
        line = chunk.data
        assert line.endswith(b"\r\n") and len(line) <= MAX_SENTENCE
        msg = pynmea2.parse(line.decode("ascii").strip(), check=True)  # raises on a bad checksum
        assert msg.talker == talker and msg.sentence_type == SENTENCES[i % 5]
        f, d = fixes[i // 5], items[i // 5]
        when = dt.datetime.fromtimestamp(int(f["utc_ns"]) // 10**7 / 100, dt.UTC)
        if msg.sentence_type in ("RMC", "GGA", "GST", "ZDA"):
            assert (msg.timestamp.hour, msg.timestamp.minute, msg.timestamp.second) == (
                when.hour,
                when.minute,
                when.second,
            )
            assert round(msg.timestamp.microsecond / 1e4) == d["cs"]
        if msg.sentence_type in ("RMC", "ZDA"):
            date = msg.datestamp if msg.sentence_type == "RMC" else dt.date(msg.year, msg.month, msg.day)
            assert (
                date == when.date()
                if msg.sentence_type == "ZDA"
                else (date.day, date.month, date.year % 100) == (when.day, when.month, when.year % 100)
            )
        ok = d["quality"] > 0
        if msg.sentence_type == "GGA":
            assert msg.gps_qual == d["quality"]
            if ok:
                assert msg.latitude == pytest.approx(d["lat"], abs=1e-5 / 60 * 0.51)
                lon = (d["lon"] + 180.0) % 360.0 - 180.0
                assert (msg.longitude - lon + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-5 / 60 * 0.51)
                assert msg.altitude == pytest.approx(d["h"], abs=5e-4)
                assert float(msg.geo_sep) == 0.0
                assert int(msg.num_sats) == d["sats"]
        if msg.sentence_type == "RMC":
            assert msg.status == ("A" if ok else "V")
            if ok:
                speed = math.hypot(d["ve"], d["vn"])
                assert msg.spd_over_grnd * KNOT == pytest.approx(speed, abs=5e-4 * KNOT * 1.01)
        if msg.sentence_type == "GST" and ok:
            assert msg.std_dev_latitude == pytest.approx(d["s"][0], abs=5e-4)
            assert msg.std_dev_longitude == pytest.approx(d["s"][1], abs=5e-4)
            assert msg.std_dev_altitude == pytest.approx(d["s"][2], abs=5e-4)


@settings(max_examples=100, deadline=None)
@given(st.lists(FIX, min_size=1, max_size=6), st.integers(1, 90))
def test_round_trip_through_the_stream_decoder(items, step):
    items = sorted(items, key=lambda d: (d["utc_s"], d["cs"]))
    items = [
        d for k, d in enumerate(items) if k == 0 or (d["utc_s"], d["cs"]) != (items[k - 1]["utc_s"], items[k - 1]["cs"])
    ]
    fixes = _fixes(items)
    data = encode_epochs(fixes, talker="GN").tobytes()
    dec = NmeaStreamDecoder(epoch_utc_ns=EPOCH_UTC)
    out = [dec.feed(data[k : k + step]) for k in range(0, len(data), step)]
    out.append(dec.flush())
    got = np.concatenate(out)
    assert dec.tally.as_dict() == {}
    assert len(got) == len(items)
    np.testing.assert_array_equal(got["utc_ns"], fixes["utc_ns"])
    np.testing.assert_array_equal(got["t_ns"], fixes["t_ns"])
    np.testing.assert_array_equal(got["quality"], fixes["quality"])
    ok = fixes["quality"] > 0
    res = math.radians(1e-5 / 60) * 0.51
    assert np.all(np.abs(got["lat"][ok] - fixes["lat"][ok]) <= res)
    dlon = (got["lon"][ok] - fixes["lon"][ok] + math.pi) % (2 * math.pi) - math.pi
    assert np.all(np.abs(dlon) <= res)
    assert np.all(np.abs(got["h"][ok] - fixes["h"][ok]) <= 5e-4 + 1e-9)
    dv = np.hypot(*(got["vel_n"][ok][:, :2] - fixes["vel_n"][ok][:, :2]).T)
    speed = np.hypot(*fixes["vel_n"][ok][:, :2].T)
    assert np.all(dv <= 5e-4 * KNOT * 1.01 + speed * math.radians(0.005) * 1.01)
    for k in ("sigma_lat", "sigma_lon", "sigma_alt"):
        assert np.all(np.abs(got[k][ok] - fixes[k][ok]) <= 5e-4 + 1e-9)
    assert np.all(np.isnan(got["lat"][~ok])) and np.all(np.isnan(got["sigma_alt"][~ok]))


def _s(body: str) -> bytes:
    return b"$" + body.encode() + b"*%02X\r\n" % checksum(body.encode())


def test_parse_errors():
    good = _s("GBZDA,120000.00,01,06,2025,00,00")
    assert parse_sentence(good)[:2] == ("GB", "ZDA")
    cases = [
        (good.replace(b"*", b"*0").replace(b"\r\n", b"") + b"\r\n", "format"),
        (good[:-5] + b"*00\r\n", "checksum"),
        (b"GBZDA,120000.00,01,06,2025,00,00*00\r\n", "format"),
        (_s("GPZDA,120000.00,01,06,2025,00,00"), "format"),  # talker not accepted
        (_s("GBGSV,1,1,00"), "unknown_id"),
        (_s("GBZDA," + "1" * 80), "length"),
        (good[:-5] + b"*G1\r\n", "format"),
    ]
    for line, kind in cases:
        with pytest.raises(CodecError) as e:
            parse_sentence(line)
        assert e.value.kind == kind, line
    assert parse_sentence(good.lower().replace(b"$gbzda", b"$GBZDA"), talkers=("GB",))  # lower-case hex accepted


def test_stream_counts_bad_sentences_and_missing_ones():
    f = _steady_fixes(6)
    chunks = [c.data for c in encode_epochs(f).chunks()]
    bad_sum = chunks[1][:-4] + (b"%02X" % (int(chunks[1][-4:-2], 16) ^ 0x21)) + b"\r\n"
    stream = (
        chunks[0]
        + bad_sum
        + b"".join(chunks[2:5])  # epoch 0: GGA bad checksum -> 1 checksum, 1 missing
        + b"line noise \x01\x02"
        + b"".join(chunks[5:10])  # 1 sync
        + chunks[10]
        + chunks[11][:30]
        + b"".join(chunks[12:15])  # GGA truncated -> 1 truncated, 1 missing
        + b"".join(chunks[15:17])
        + chunks[16]
        + b"".join(chunks[17:20])  # GGA twice -> 1 duplicate
        + b"".join(chunks[20:24])  # ZDA of epoch 4 lost: closed by epoch 5 -> 1 missing
        + b"".join(chunks[25:30])
    )
    for step in (1, 7, len(stream)):
        dec = NmeaStreamDecoder(epoch_utc_ns=EPOCH_UTC)
        got = np.concatenate([dec.feed(stream[k : k + step], k) for k in range(0, len(stream), step)] + [dec.flush()])
        assert dec.tally.as_dict() == {"checksum": 1, "missing": 3, "sync": 1, "truncated": 1, "duplicate": 1}, step
        assert len(got) == 6
        np.testing.assert_array_equal(got["t_ns"], f["t_ns"])
        assert math.isnan(got["h"][0]) and got["h"][1] == pytest.approx(380.0)  # GGA of epoch 0 was bad


def test_date_rolls_over_midnight_without_a_date_field():
    f = _fixes(
        [
            {
                "utc_s": 1_748_822_399,
                "cs": 50,
                "lat": 1.0,
                "lon": 2.0,
                "h": 3.0,
                "ve": 0.0,
                "vn": 0.0,
                "s": (1.0, 1.0, 1.0),
                "sats": 9,
                "hdop": 1.0,
                "quality": 1,
            },
            {
                "utc_s": 1_748_822_400,
                "cs": 50,
                "lat": 1.0,
                "lon": 2.0,
                "h": 3.0,
                "ve": 0.0,
                "vn": 0.0,
                "s": (1.0, 1.0, 1.0),
                "sats": 9,
                "hdop": 1.0,
                "quality": 1,
            },
        ]
    )
    chunks = [c.data for c in encode_epochs(f).chunks()]
    dec = NmeaStreamDecoder()
    # second epoch without RMC and ZDA: its date comes from the first, plus the day it rolled over
    got = np.concatenate([dec.feed(b"".join(chunks[:5])), dec.feed(b"".join(chunks[6:9])), dec.flush()])
    np.testing.assert_array_equal(got["utc_ns"], f["utc_ns"])
    assert dec.tally["missing"] == 2


def test_outage_sentences_and_range_errors():
    f = _fixes(
        [
            {
                "utc_s": 1_748_736_000,
                "cs": 0,
                "lat": 0.0,
                "lon": 0.0,
                "h": 0.0,
                "ve": 0.0,
                "vn": 0.0,
                "s": (1.0, 1.0, 1.0),
                "sats": 3,
                "hdop": 9.9,
                "quality": 0,
            }
        ]
    )
    f["lat"] = np.nan  # a receiver without a fix has no position: nothing of it is sent
    lines = [c.data for c in encode_epochs(f).chunks()]
    assert lines[0].startswith(b"$GBRMC,000000.00,V,,,,,,,010625,,,N,V*")
    assert lines[1].startswith(b"$GBGGA,000000.00,,,,,0,03,,,M,0.0,M,,*")
    g = _fixes(
        [
            {
                "utc_s": 0,
                "cs": 0,
                "lat": 0.0,
                "lon": 0.0,
                "h": 0.0,
                "ve": 0.0,
                "vn": 0.0,
                "s": (1.0, 1.0, 1.0),
                "sats": 3,
                "hdop": 1.0,
                "quality": 1,
            }
        ]
    )
    for key, value in [("lat", 1.6), ("sigma_alt", -1.0), ("h", np.nan)]:
        bad = g.copy()
        bad[key] = value
        with pytest.raises(CodecError) as e:
            encode_epochs(bad)
        assert e.value.kind == "range"
    with pytest.raises(CodecError):
        encode_epochs(g, talker="GP")


def test_outage_styles():
    f = _steady_fixes(3)
    lines = [c.data for c in encode_epochs(f, outage_style=[0, 1, 2]).chunks()]
    assert len(lines) == 10  # the silent epoch sends nothing
    assert lines[5].startswith(b"$GBRMC,000001.00,V,") and b",0,12," in lines[6]
    assert f["quality"].tolist() == [1, 1, 1]  # the caller's records are left alone
    with pytest.raises(CodecError):
        encode_epochs(f, outage_style=[0, 3, 0])
