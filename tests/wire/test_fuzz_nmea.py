"""The NMEA stream decoder under hostile input: every input decodes or is counted by kind
(never another exception), every byte is accounted for, its state survives, and the
result does not depend on how the bytes are split into reads."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.errors import CodecError
from bench.wire.nmea import GNSS_FIX_DTYPE, checksum, encode_epochs
from bench.wire.nmea_fields import decode_fields, parse_sentence
from bench.wire.nmea_stream import NMEA_KINDS, NmeaStreamDecoder

EPOCH_UTC = 1_748_736_000 * 10**9  # 2025-06-01T00:00:00Z
LINE_KINDS = ("checksum", "format", "unknown_id", "range", "duplicate")
HOSTILE = (
    "nan", "inf", "-inf", "1e400", "1e308", "999999", "9999", "-1", "290223", "310299", "000000", "1_0", "+5",
    " 5", "0x1F", "", "99999999999999999999", "12.5.3", "-0", "256", "13", "00", "2262", "9000.0", "18100.0",
)  # fmt: skip


def _fixes(n: int, t0_s: int) -> np.ndarray:
    f = np.zeros(n, GNSS_FIX_DTYPE)
    f["utc_ns"] = EPOCH_UTC + (t0_s + np.arange(n)) * 10**9
    f["t_ns"] = f["utc_ns"] - EPOCH_UTC
    f["lat"], f["lon"], f["h"], f["quality"], f["sats"], f["hdop"] = 0.6, 1.9, 380.0, 1, 12, 0.9
    f["vel_n"] = (1.0, 2.0, 0.0)
    f["sigma_lat"], f["sigma_lon"], f["sigma_alt"] = 1.0, 1.5, 2.0
    return f


BASE = [c.data for c in encode_epochs(_fixes(3, 0)).chunks()]  # 00:00:00 .. 00:00:02
TAIL = encode_epochs(_fixes(4, 43_200)).tobytes()  # 12:00:00 .. 12:00:03, decoded after the garbage


def _s(body: str) -> bytes:
    return b"$" + body.encode() + b"*%02X\r\n" % checksum(body.encode())


def _mutate(args) -> bytes:
    line, field, value, fix_sum = args
    parts = line[1 : line.index(b"*")].decode().split(",")
    parts[1 + field % (len(parts) - 1)] = value
    body = ",".join(parts).encode()
    return b"$" + body + (b"*%02X\r\n" % checksum(body) if fix_sum else line[line.index(b"*") :])


PIECE = st.one_of(
    st.sampled_from(BASE),
    st.tuples(st.sampled_from(BASE), st.integers(0, 13), st.sampled_from(HOSTILE), st.booleans()).map(_mutate),
    st.tuples(
        st.sampled_from(BASE), st.integers(0, 13), st.text("0123456789.-+eE,$*\r\nainfAV", max_size=12), st.just(True)
    ).map(_mutate),
    st.binary(max_size=40),
    st.tuples(st.sampled_from(BASE), st.integers(1, 60)).map(lambda a: a[0][: a[1]]),  # a cut sentence
    st.integers(60, 120).map(lambda k: b"$" + b"A," * (k // 2)),  # no CR LF within 82 characters
)
STREAM = st.lists(PIECE, max_size=25).map(b"".join)
CUTS = st.lists(st.integers(1, 90), min_size=1, max_size=60)


def _pieces(data: bytes, cuts: list[int] | None) -> list[bytes]:
    """``data`` cut in pieces of the sizes ``cuts`` (cycled; None: at once)."""
    out, pos, k = [], 0, 0
    while pos < len(data):
        step = len(data) if cuts is None else cuts[k % len(cuts)]
        out.append(data[pos : pos + step])
        pos, k = pos + step, k + 1
    return out


def _feed(reads: list[tuple[bytes, int]]):
    """Feed reads ``(bytes, arrival)``, then end the stream."""
    dec = NmeaStreamDecoder(epoch_utc_ns=EPOCH_UTC)
    out = [dec.feed(data, rx) for data, rx in reads] + [dec.flush(9)]
    return dec, np.concatenate(out)


def _decode(data: bytes, cuts: list[int] | None):
    return _feed([(p, 7) for p in _pieces(data, cuts)])


def _records(dec: NmeaStreamDecoder) -> list[tuple]:
    return [(b.kind, b.data, b.t_ns) for b in dec.tally.bad]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(STREAM, CUTS)
def test_any_bytes_decode_or_are_counted_and_every_byte_is_accounted_for(data, cuts):
    dec, fixes = _decode(data, cuts)
    assert set(dec.tally.as_dict()) <= set(NMEA_KINDS)
    assert dec.bytes_in == len(data) == dec.bytes_good + dec.bytes_bad
    assert dec.lines == dec.sentences + sum(dec.tally[k] for k in LINE_KINDS)
    assert np.all((fixes["quality"] <= 8) & ~np.isinf(fixes["vel_n"]).any(axis=1))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(STREAM, CUTS)
def test_the_split_into_reads_changes_nothing(data, cuts):
    """At once, byte by byte and in random pieces: the same fixes, counts and kept bad
    frames; with the bytes of each read stamped by its arrival, the same stamps."""
    whole, fixes = _decode(data, None)
    for split in (cuts, [1]):
        dec, got = _decode(data, split)
        assert got.tobytes() == fixes.tobytes()
        assert dec.tally.as_dict() == whole.tally.as_dict()
        assert _records(dec) == _records(whole)
    # reads arriving at different times, each cut further: the stamps follow the bytes
    reads = [(p, 100 + 10 * k) for k, p in enumerate(_pieces(data, cuts))]
    ref, ref_fixes = _feed(reads)
    dec, got = _feed([(p[a:b], t) for p, t in reads for a, b in ((0, len(p) // 2), (len(p) // 2, len(p)))])
    assert got.tobytes() == ref_fixes.tobytes() and _records(dec) == _records(ref)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(STREAM, CUTS)
def test_after_any_garbage_valid_input_decodes_exactly(data, cuts):
    _, fresh = _decode(TAIL, None)
    assert len(fresh) == 4
    _, got = _decode(data + b"\r\n" + TAIL, cuts)
    # the first tail epoch may take in an epoch the garbage left open; the rest are exact
    assert got[-3:].tobytes() == fresh[1:].tobytes()


# ---------------------------------------------------------------------------- the crash signatures
GGA = "GBGGA,120000.00,3422.64806,N,10851.71886,E,{q},{sats},0.9,380.000,M,0.0,M,,"
RMC = "GBRMC,120000.00,A,{lat},N,10851.71886,E,{sog},{cog},{date},,,A,S"
VTG = "GBVTG,{cog},T,,M,4.347,N,8.050,K,A"
ZDA = "GBZDA,{tod},{d},{m},{y},00,00"
Z = {"tod": "120000.00", "d": "01", "m": "06", "y": "2025"}
R = {"lat": "3422.64806", "sog": "4.347", "cog": "26.57", "date": "010625"}


@pytest.mark.parametrize(
    ("body", "kind"),
    [
        (ZDA.format(**{**Z, "m": "13"}), "range"),  # month 13 (ValueError in datetime.date)
        (ZDA.format(**{**Z, "d": "29", "m": "02", "y": "2023"}), "range"),  # 29 February of a common year
        (ZDA.format(**{**Z, "d": "00"}), "range"),
        (ZDA.format(**{**Z, "y": "9999"}), "range"),  # beyond int64 nanoseconds (OverflowError)
        (ZDA.format(**{**Z, "y": "1969"}), "range"),
        (ZDA.format(**{**Z, "tod": "250000.00"}), "range"),
        (ZDA.format(**{**Z, "tod": "12000e.00"}), "format"),
        (RMC.format(**{**R, "date": "290223"}), "range"),
        (RMC.format(**{**R, "date": "999999"}), "range"),
        (RMC.format(**{**R, "cog": "inf"}), "format"),  # sin(inf)
        (VTG.format(cog="1e400"), "format"),  # float overflow to inf, then sin(inf)
        (VTG.format(cog="nan"), "format"),
        (VTG.format(cog="400.0"), "range"),
        (RMC.format(**{**R, "sog": "-1"}), "range"),
        (RMC.format(**{**R, "lat": "9500.00000"}), "range"),
        (RMC.format(**{**R, "lat": "3460.00000"}), "range"),  # 60 arcmin
        (RMC.format(**{**R, "lat": "1_022.5"}), "format"),
        (GGA.format(q="nan", sats="12"), "format"),  # int(nan)
        (GGA.format(q="1e400", sats="12"), "format"),  # int(inf)
        (GGA.format(q="9", sats="12"), "range"),
        (GGA.format(q="1", sats="9999"), "range"),  # over 255: the fix record's uint8 broke the decoder
        (GGA.format(q="1", sats="-1"), "format"),
        (GGA.format(q="1", sats="12.5"), "format"),
        ("GBGST,120000.00,,1.000,1.000,0.0,nan,1.000,2.000", "format"),
        ("GBGST,120000.00,,1.000,1.000,0.0,-1.0,1.000,2.000", "range"),
    ],
)
def test_a_hostile_field_is_one_counted_event_and_the_decoder_goes_on(body, kind):
    line = _s(body)
    with pytest.raises(CodecError) as err:
        decode_fields(*parse_sentence(line)[1:])
    assert err.value.kind == kind
    _, fresh = _decode(TAIL, None)
    for split in (None, [1], [13]):
        dec, got = _decode(line + TAIL, split)
        assert dec.tally.as_dict() == {kind: 1}, split
        assert got.tobytes() == fresh.tobytes()


def test_a_date_moved_past_the_int64_limit_by_midnights_is_a_range_event():
    """ZDA of the last representable day, then epochs without a date: the one whose UTC
    no longer fits int64 nanoseconds is counted, not handed on (nor a crash on the next read)."""
    lines = [
        _s(GGA.format(q="1", sats="12").replace("120000.00", "230000.00")),
        _s(ZDA.format(tod="230000.00", d="10", m="04", y="2262")),
        _s(GGA.format(q="1", sats="12").replace("120000.00", "003000.00")),  # 2262-04-11 00:30: fits
        _s(GGA.format(q="1", sats="12").replace("120000.00", "235000.00")),  # 2262-04-11 23:50: does not
    ]
    dec = NmeaStreamDecoder()
    got = [dec.feed(b"".join(lines)), dec.flush()]
    assert sum(len(g) for g in got) == 2 and dec.tally["range"] == 1
    _, fresh = _decode(TAIL, None)
    dec2, got2 = _feed([(b"".join(lines), 7), (TAIL, 7)])
    assert got2[-4:].tobytes() == fresh.tobytes() and dec2.tally["range"] == 1


def test_framing_is_decided_on_82_bytes_whatever_the_reads():
    """A '$' with neither CR LF nor '$' in its 82 bytes is one ``length`` run up to the next
    '$', however the bytes arrive (before: ``length`` in small reads, ``truncated`` at once)."""
    data = b"$GBGGA," + b"1" * 100 + TAIL[:-2] + b"\r\n"
    counts = {str(split): _decode(data, split)[0].tally.as_dict() for split in (None, [1], [40], [83])}
    assert all(c == {"length": 1} for c in counts.values()), counts
    long_line = b"$GBGGA," + b"1" * 80 + b"\r\nnoise" + TAIL
    counts = {str(split): _decode(long_line, split)[0].tally.as_dict() for split in (None, [1], [50])}
    assert all(c == {"length": 1} for c in counts.values()), counts
