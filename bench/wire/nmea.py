"""NMEA 0183 (version 4.11) sentences of the BDS receiver: RMC, GGA, GST, VTG, ZDA.

Encoding: :func:`encode_epochs` turns fix epochs (:data:`GNSS_FIX_DTYPE`, SI) into the
five sentences per epoch in the ICD order RMC, GGA, GST, VTG, ZDA, each a chunk of a
:class:`~bench.frames.SerialBatch`. The numeric work (time of day with carry, degrees and
minutes, knots, course) is vectorised; the checksums are one ``xor.reduceat`` over all
sentences.

Fields (``f`` decimals as written):

* time ``hhmmss.ss`` is the UTC of the measurement epoch, rounded to 10 ms;
* latitude ``ddmm.mmmmm`` and longitude ``dddmm.mmmmm`` (1e-5 arcmin, about 2 cm);
* GGA altitude is the ellipsoidal height (m, 3 decimals) and geoid separation ``0.0``;
* speed over ground in knots (3 decimals, 1 kn = 1852/3600 m/s) and km/h (3 decimals),
  course over ground true, degrees (2 decimals), from the east and north velocity;
* GST: RMS of range residuals empty (not modelled), semi-major and semi-minor axis and
  orientation of the error ellipse from the latitude and longitude sigmas (uncorrelated),
  then the 1-sigma latitude, longitude and altitude errors (m, 3 decimals);
* a fix of quality 0 (outage, "no fix") sends RMC status ``V``, mode ``N``, GGA quality 0
  and empty position, speed and sigma fields; ZDA still carries the receiver's time.

Decoding, strict and total, is in :mod:`bench.wire.nmea_fields` (one sentence:
:func:`~bench.wire.nmea_fields.parse_sentence`, :func:`~bench.wire.nmea_fields.decode_fields`)
and :mod:`bench.wire.nmea_stream` (the byte stream).
"""

from __future__ import annotations

import math

import numpy as np

from bench.errors import CodecError
from bench.frames import SerialBatch
from bench.wire.bits import round_div

__all__ = [
    "GNSS_FIX_DTYPE",
    "SENTENCES",
    "TALKERS",
    "KNOT",
    "MAX_SENTENCE",
    "encode_epochs",
    "checksum",
    "quality_mode",
]

#: A fix epoch in SI, as the encoder takes it and the stream decoder gives it back.
GNSS_FIX_DTYPE = np.dtype(
    [
        ("t_ns", "<i8"),  # bench time of the measurement epoch
        ("utc_ns", "<i8"),  # UTC of the measurement epoch, ns since 1970-01-01
        ("rx_ns", "<i8"),  # arrival of the epoch's last sentence (decoder), or 0
        ("lat", "<f8"),  # rad
        ("lon", "<f8"),  # rad
        ("h", "<f8"),  # ellipsoidal height, m
        ("vel_n", "<f8", (3,)),  # ENU, m/s (decoded: E and N from speed and course, U NaN)
        ("sigma_lat", "<f8"),  # m
        ("sigma_lon", "<f8"),  # m
        ("sigma_alt", "<f8"),  # m
        ("sats", "u1"),
        ("hdop", "<f8"),
        ("quality", "u1"),  # GGA fix quality: 0 none, 1 SPS, 2 differential, 4 RTK fixed, 5 RTK float, 6 DR
    ]
)

#: Sentence types of an epoch, in the order the ICD sends them.
SENTENCES = ("RMC", "GGA", "GST", "VTG", "ZDA")
TALKERS = ("GB", "BD", "GN")
KNOT = 1852.0 / 3600.0  # m/s
#: NMEA 0183 limit: 82 characters from '$' to LF inclusive.
MAX_SENTENCE = 82

_MODES = {0: "N", 1: "A", 2: "D", 3: "A", 4: "R", 5: "F", 6: "E", 7: "M", 8: "S"}


def quality_mode(quality: int) -> str:
    """The RMC/VTG mode indicator of a GGA quality (0 N, 1 A, 2 D, 4 R, 5 F, 6 E, 7 M, 8 S)."""
    return _MODES.get(int(quality), "N")


def checksum(body: bytes) -> int:
    """XOR of the bytes between '$' and '*'."""
    return int(np.bitwise_xor.reduce(np.frombuffer(body, np.uint8))) if body else 0


def _latlon(values: np.ndarray, width: int, pos: str, neg: str) -> tuple[list[str], list[str]]:
    deg = np.degrees(np.abs(values))
    total = np.rint(deg * 60e5).astype(np.int64)  # 1e-5 arcmin
    whole, frac = np.divmod(total, 60 * 100000)
    minutes, mfrac = np.divmod(frac, 100000)
    text = [
        f"{d:0{width}d}{m:02d}.{f:05d}"
        for d, m, f in zip(whole.tolist(), minutes.tolist(), mfrac.tolist(), strict=True)
    ]
    hemi = [neg if v < 0 else pos for v in values.tolist()]
    return text, hemi


def encode_epochs(fixes: np.ndarray, *, talker: str = "GB", at_ns=None, outage_style=None) -> SerialBatch:
    """The five sentences of every epoch of ``fixes`` (:data:`GNSS_FIX_DTYPE`) as chunks.

    ``at_ns`` (N,) is when each epoch's sentences are due on the link (the measurement
    time plus the receiver latency); default the epochs' ``t_ns``. ``outage_style`` (N,),
    optional, is the receiver's behaviour in an outage per epoch (ICD 4): 0 none, 1 "no
    fix" (sent as quality 0: RMC status V, GGA quality 0), 2 "silent" (nothing sent).
    Raises ``CodecError("range")`` for a latitude beyond +-90 deg, a negative sigma or a
    value that does not fit its field.
    """
    if talker not in TALKERS:
        raise CodecError("range", f"NMEA talker: expected one of {', '.join(TALKERS)}, found {talker!r}")
    fixes = np.atleast_1d(fixes)
    n = fixes.shape[0]
    at_ns = fixes["t_ns"] if at_ns is None else np.broadcast_to(np.asarray(at_ns, np.int64), (n,))
    if outage_style is not None:
        style = np.broadcast_to(np.asarray(outage_style), (n,))
        if np.any((style < 0) | (style > 2)):
            raise CodecError("range", "NMEA outage_style: expected 0 none, 1 no fix, 2 silent")
        fixes = fixes.copy()
        fixes["quality"][style == 1] = 0
        fixes, at_ns = fixes[style != 2], at_ns[style != 2]
        n = fixes.shape[0]
    if n == 0:
        return SerialBatch.empty()
    q = fixes["quality"].astype(int)
    ok = q > 0
    for name in ("lat", "lon", "h", "sigma_lat", "sigma_lon", "sigma_alt", "hdop"):
        if not np.all(np.isfinite(fixes[name][ok])):
            raise CodecError("range", f"NMEA fix {name}: value is not finite")
    if not np.all(np.isfinite(fixes["vel_n"][ok][:, :2])):
        raise CodecError("range", "NMEA fix vel_n: value is not finite")
    if np.any(np.abs(fixes["lat"][ok]) > math.pi / 2 + 1e-12):
        raise CodecError("range", "NMEA fix lat: beyond +-90 deg")
    for name in ("sigma_lat", "sigma_lon", "sigma_alt", "hdop"):
        if np.any(fixes[name][ok] < 0):
            raise CodecError("range", f"NMEA fix {name}: negative")
    if np.any(fixes["utc_ns"] < 0):
        raise CodecError("range", "NMEA fix utc_ns: before 1970")
    if np.any(fixes["h"][ok] <= -1e5) or np.any(fixes["h"][ok] >= 1e7):
        raise CodecError("range", "NMEA fix h: outside (-100 km, 10000 km)")

    cs = round_div(fixes["utc_ns"], 10_000_000)  # centiseconds since 1970
    day, cod = np.divmod(cs, 8_640_000)
    hh, rem = np.divmod(cod, 360_000)
    mm, rem = np.divmod(rem, 6000)
    ss, cc = np.divmod(rem, 100)
    dates = day.astype("datetime64[D]")
    years = dates.astype("datetime64[Y]").astype(np.int64) + 1970
    months = dates.astype("datetime64[M]").astype(np.int64) % 12 + 1
    days = (dates - dates.astype("datetime64[M]").astype("datetime64[D]")).astype(np.int64) + 1
    times = [
        f"{a:02d}{b:02d}{c:02d}.{d:02d}"
        for a, b, c, d in zip(hh.tolist(), mm.tolist(), ss.tolist(), cc.tolist(), strict=True)
    ]
    lat_t, lat_h = _latlon(np.where(ok, fixes["lat"], 0.0), 2, "N", "S")
    lon_wrapped = np.where(ok, (fixes["lon"] + math.pi) % (2 * math.pi) - math.pi, 0.0)
    lon_t, lon_h = _latlon(lon_wrapped, 3, "E", "W")
    ve, vn = np.where(ok, fixes["vel_n"][:, 0], 0.0), np.where(ok, fixes["vel_n"][:, 1], 0.0)
    speed = np.hypot(ve, vn)
    cog_cdeg = np.rint(np.degrees(np.arctan2(ve, vn)) * 100).astype(np.int64) % 36000
    sog_kn = speed / KNOT
    sog_kmh = speed * 3.6
    s_lat, s_lon = fixes["sigma_lat"], fixes["sigma_lon"]
    smaj, smin = np.maximum(s_lat, s_lon), np.minimum(s_lat, s_lon)
    orient = np.where(s_lat >= s_lon, 0.0, 90.0)

    sentences: list[str] = []
    for i in range(n):
        t = times[i]
        if ok[i]:
            mode = quality_mode(q[i])
            pos = f"{lat_t[i]},{lat_h[i]},{lon_t[i]},{lon_h[i]}"
            cog = f"{cog_cdeg[i] // 100}.{cog_cdeg[i] % 100:02d}"
            rmc = f"RMC,{t},A,{pos},{sog_kn[i]:.3f},{cog},{days[i]:02d}{months[i]:02d}{years[i] % 100:02d},,,{mode},S"
            gga = (
                f"GGA,{t},{pos},{q[i]},{int(fixes['sats'][i]):02d},{fixes['hdop'][i]:.1f},{fixes['h'][i]:.3f},M,0.0,M,,"
            )
            gst = (
                f"GST,{t},,{smaj[i]:.3f},{smin[i]:.3f},{orient[i]:.1f},{s_lat[i]:.3f},{s_lon[i]:.3f},"
                f"{fixes['sigma_alt'][i]:.3f}"
            )
            vtg = f"VTG,{cog},T,,M,{sog_kn[i]:.3f},N,{sog_kmh[i]:.3f},K,{mode}"
        else:
            rmc = f"RMC,{t},V,,,,,,,{days[i]:02d}{months[i]:02d}{years[i] % 100:02d},,,N,V"
            gga = f"GGA,{t},,,,,0,{int(fixes['sats'][i]):02d},,,M,0.0,M,,"
            gst = f"GST,{t},,,,,,,"
            vtg = "VTG,,T,,M,,N,,K,N"
        zda = f"ZDA,{t},{days[i]:02d},{months[i]:02d},{years[i]:04d},00,00"
        sentences += [talker + rmc, talker + gga, talker + gst, talker + vtg, talker + zda]
    bodies = [s.encode("ascii") for s in sentences]
    lengths = np.fromiter((len(b) for b in bodies), np.int64, len(bodies))
    starts = np.zeros(len(bodies), np.int64)
    np.cumsum(lengths[:-1], out=starts[1:])
    sums = np.bitwise_xor.reduceat(np.frombuffer(b"".join(bodies), np.uint8), starts)
    out = [b"$" + b + b"*%02X\r\n" % c for b, c in zip(bodies, sums.tolist(), strict=True)]
    too_long = [o for o in out if len(o) > MAX_SENTENCE]
    if too_long:
        raise CodecError("range", f"NMEA sentence longer than {MAX_SENTENCE} characters: {too_long[0][:40]!r}...")
    offsets = np.zeros(len(out) + 1, np.int64)
    np.cumsum([len(o) for o in out], out=offsets[1:])
    return SerialBatch(np.repeat(at_ns, 5), offsets, b"".join(out))
