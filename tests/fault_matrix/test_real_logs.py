"""The fault matrix (issue 33), real logs in: field logs in the formats engineers have.

On 57b1bce ``bench replay --imu-log`` took only the ICD's own byte stream: a PSINS ``.imu``,
a KF-GINS ``imu.txt``, a gnss-ins-sim output and a ``gnss.pos`` were refused ("no ICD IMU
frame ...; found text") without saying how to convert; ``bench score`` of a field-log
replay exited 3 ("no test case attached") where docs/run_engine.md said it judges it; a
log without ``--epoch`` was silently dated 2025-06-01; ``bench imu allan`` printed the PSINS
header's scale constant as "gravity". Each row below fails there and passes now (what
every row checks: tests/fault_matrix/test_inputs.py).

The conversions are checked at the stream level with a decoder written here from ICD.md
section 3 alone (not the bench's): the produced frames are well formed, one per sample at
the log's own times, and the summed increments equal the source file's to one LSB
(1e-9 rad, 1e-8 m/s) over the whole log.
"""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path

import numpy as np
import pytest

from tests.fault_matrix.matrix import bench
from tests.run.duts.icd_select import crc16

HERE = Path(__file__).parent
PSINS = HERE.parent / "data" / "psins_lasergyro_10min.imu"
CASE = HERE / "data" / "real_logs_case.toml"
LSB_TH, LSB_V = 1e-9, 1e-8


# ----------------------------------------------------------------------------- ICD 3, from ICD.md
# CRC-16/CCITT-FALSE as ICD 1 states it, written without the bench (the sample external DUT's)
_crc16 = crc16


def decode_icd(data: bytes, *, check_crc: int = 50) -> dict[str, np.ndarray]:
    """Frames of a byte stream that holds nothing but back-to-back ICD 3 frames: time (us),
    counter, raw angle and velocity increments (int), status. CRC checked on the first
    ``check_crc`` frames and the last (pure Python is slow)."""
    assert len(data) % 42 == 0, len(data)
    n = len(data) // 42
    rec = np.frombuffer(data, dtype=np.dtype([("sync", "<u2"), ("len", "u1"), ("counter", "u1"), ("t", "<u8"),
                                              ("dth", "<i4", (3,)), ("dv", "<i4", (3,)), ("status", "<u2"),
                                              ("temp", "<i2"), ("crc", "<u2")]))
    assert np.all(rec["sync"] == 0x55AA) and np.all(rec["len"] == 36)
    for k in [*range(min(n, check_crc)), n - 1]:
        frame = data[42 * k: 42 * k + 42]
        assert struct.unpack("<H", frame[40:42])[0] == _crc16(frame[2:40]), k
    assert np.all(np.diff(rec["counter"].astype(int)) % 256 == 1)
    return {"t_us": rec["t"].astype(np.int64), "dth": rec["dth"].astype(np.int64), "dv": rec["dv"].astype(np.int64),
            "status": rec["status"]}


def encode_icd(t_us: np.ndarray, dth_raw: np.ndarray, dv_raw: np.ndarray) -> bytes:
    """ICD 3 frames of raw increments (for the rows that must run on 57b1bce too)."""
    out = bytearray()
    for k in range(len(t_us)):
        body = struct.pack("<BBQ3i3iHh", 36, k % 256, int(t_us[k]), *map(int, dth_raw[k]), *map(int, dv_raw[k]),
                           0x3F, 2500)
        out += b"\xaa\x55" + body + struct.pack("<H", _crc16(body))
    return bytes(out)


def _stream(path: Path, fmt: str | None = None) -> bytes:
    from bench.exchange.field_logs import convert_field_logs

    conv = convert_field_logs(path, None, imu_format=fmt)
    assert conv.imu_data is not None
    return conv.imu_data


def _psins_counts(path: Path) -> tuple[np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]:
    """The PSINS log read here: raw counts (N, 6), the header's interval, gyro and accel LSBs."""
    lines = [ln for ln in path.read_text().splitlines() if ln.strip() and not ln.lstrip().startswith("%")]
    p2 = [float(v) for v in lines[1].split()]
    p3 = [float(v) for v in lines[2].split()]
    counts = np.array([[float(v) for v in ln.split()] for ln in lines[3:]])
    g = p2[5]
    return counts, p2, p2[4] * 1e-3, np.radians(np.array(p3[:3]) / 3600.0), np.array(p3[3:6]) * 1e-6 * g


# ----------------------------------------------------------------------------- readers, bit-exact
def test_psins_log_becomes_icd_frames_at_its_own_rate_with_exact_sums():
    counts, _, dt, glsb, alsb = _psins_counts(PSINS)
    f = decode_icd(_stream(PSINS))
    n = len(counts)
    assert len(f["t_us"]) == n == 60_000
    assert np.array_equal(f["t_us"], np.arange(1, n + 1) * round(dt * 1e6))  # 100 Hz, first interval from 0
    assert np.all(f["status"] == 0x3F)
    # PSINS axes are X-right, Y-forward, Z-up: the ICD's own; sums to one LSB over the whole log
    want_th = (counts[:, 0:3].sum(axis=0) * glsb) / LSB_TH
    want_v = (counts[:, 3:6].sum(axis=0) * alsb) / LSB_V
    assert np.all(np.abs(f["dth"].sum(axis=0) - want_th) <= 1.0), (f["dth"].sum(axis=0), want_th)
    assert np.all(np.abs(f["dv"].sum(axis=0) - want_v) <= 1.0)
    # and every frame within one LSB of its own sample (the remainder is carried, never lost)
    assert np.max(np.abs(f["dth"] - counts[:, 0:3] * glsb / LSB_TH)) <= 1.0
    running = np.cumsum(f["dth"], axis=0) - np.cumsum(counts[:, 0:3] * glsb / LSB_TH, axis=0)
    assert np.max(np.abs(running)) <= 0.5 + 1e-6


def _kfgins_file(path: Path, n: int = 2000, rate: float = 200.0, sow0: float = 345_600.0, seed: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = sow0 + np.arange(1, n + 1) / rate
    inc = np.column_stack([rng.normal(0, 1e-4, (n, 3)), rng.normal([0.01, 0, -9.79 / rate], 1e-3, (n, 3))])
    with path.open("w") as fh:
        for k in range(n):
            fh.write(f"{t[k]:.9f} " + " ".join(f"{v:.12e}" for v in inc[k]) + "\n")
    return np.column_stack([t, inc])


def test_kfgins_imu_txt_forward_right_down_becomes_rfu_frames_with_exact_sums(tmp_path):
    src = tmp_path / "imu.txt"
    rows = _kfgins_file(src)
    f = decode_icd(_stream(src))
    assert len(f["t_us"]) == len(rows)
    # GPS sow: bench time zero at the whole second before the first interval (345600 s)
    assert np.array_equal(f["t_us"], np.rint((rows[:, 0] - 345_600.0) * 1e6).astype(np.int64))
    frd_th, frd_v = rows[:, 1:4].sum(axis=0), rows[:, 4:7].sum(axis=0)
    rfu_th = np.array([frd_th[1], frd_th[0], -frd_th[2]])  # right = y, forward = x, up = -z
    rfu_v = np.array([frd_v[1], frd_v[0], -frd_v[2]])
    assert np.all(np.abs(f["dth"].sum(axis=0) - rfu_th / LSB_TH) <= 1.0)
    assert np.all(np.abs(f["dv"].sum(axis=0) - rfu_v / LSB_V) <= 1.0)


def _gnss_ins_sim(folder: Path, n: int = 1001, fs: float = 100.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    folder.mkdir()
    t = np.arange(n) / fs
    gyro = np.column_stack([0.5 * np.sin(t), 0.01 * np.ones(n), 2.0 * np.cos(3 * t)])  # deg/s, FRD
    acc = np.column_stack([0.3 * np.ones(n), 0.1 * np.sin(t), -9.8 + 0.05 * t])  # m/s^2, FRD
    np.savetxt(folder / "time.csv", t, delimiter=",", header="time (sec)", comments="", fmt="%.6f")
    np.savetxt(folder / "gyro-0.csv", gyro, delimiter=",", header="gyro_x (deg/s),gyro_y (deg/s),gyro_z (deg/s)",
               comments="", fmt="%.12e")
    np.savetxt(folder / "accel-0.csv", acc, delimiter=",",
               header="accel_x (m/s^2),accel_y (m/s^2),accel_z (m/s^2)", comments="", fmt="%.12e")
    return t, gyro, acc


def test_gnss_ins_sim_rates_become_increments_by_the_trapezoid_with_exact_sums(tmp_path):
    folder = tmp_path / "sim"
    t, gyro, acc = _gnss_ins_sim(folder)
    f = decode_icd(_stream(folder))
    assert len(f["t_us"]) == len(t) - 1  # one interval between each two samples
    assert np.array_equal(f["t_us"], np.rint(t[1:] * 1e6).astype(np.int64))
    dt = np.diff(t)[:, None]
    th = np.radians(0.5 * (gyro[1:] + gyro[:-1]) * dt).sum(axis=0)
    dv = (0.5 * (acc[1:] + acc[:-1]) * dt).sum(axis=0)
    assert np.all(np.abs(f["dth"].sum(axis=0) - np.array([th[1], th[0], -th[2]]) / LSB_TH) <= 1.0)
    assert np.all(np.abs(f["dv"].sum(axis=0) - np.array([dv[1], dv[0], -dv[2]]) / LSB_V) <= 1.0)


@pytest.mark.parametrize("axes", ["FLU", "matrix"])
def test_a_declared_csv_log_is_read_as_its_toml_says(tmp_path, axes):
    rng = np.random.default_rng(5)
    n = 500
    t_ms = 1000.0 + np.arange(n) * 5.0  # 200 Hz, times in ms of its own clock
    gyro = rng.normal(0, 2.0, (n, 3))  # deg/s, log axes
    acc = rng.normal([0, 0, 9.8], 0.1, (n, 3))  # m/s^2
    log = tmp_path / "drive.csv"
    with log.open("w") as fh:
        fh.write("# my logger v2\nt_ms,wx,wy,wz,ax,ay,az,temp\n")
        for k in range(n):
            fh.write(f"{t_ms[k]:.3f}," + ",".join(f"{v:.9f}" for v in (*gyro[k], *acc[k])) + ",25.0\n")
    m = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # FLU -> RFU
    if axes == "FLU":
        axes_toml = '"FLU"'
    else:  # a 30 deg yaw mounting on top of FLU
        c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
        m = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ m
        axes_toml = "[" + ", ".join("[" + ", ".join(f"{v:.17g}" for v in row) + "]" for row in m) + "]"
    (tmp_path / "drive.toml").write_text(
        'columns = ["t", "wx", "wy", "wz", "ax", "ay", "az", "temp"]\nskip_lines = 2\n'
        'time_column = "t"\ntime_unit = "ms"\ntime_base = "bench"\n'
        'gyro_columns = ["wx", "wy", "wz"]\ngyro_unit = "deg/s"\n'
        'accel_columns = ["ax", "ay", "az"]\naccel_unit = "m/s^2"\n'
        f"axes = {axes_toml}\n")
    f = decode_icd(_stream(log))
    assert len(f["t_us"]) == n - 1
    assert np.array_equal(f["t_us"], np.rint((t_ms[1:] - t_ms[0]) * 1e3).astype(np.int64))
    dt = np.diff(t_ms)[:, None] * 1e-3
    th = m @ np.radians(0.5 * (gyro[1:] + gyro[:-1]) * dt).sum(axis=0)
    dv = m @ (0.5 * (acc[1:] + acc[:-1]) * dt).sum(axis=0)
    assert np.all(np.abs(f["dth"].sum(axis=0) - th / LSB_TH) <= 1.0 + 1e-6)
    assert np.all(np.abs(f["dv"].sum(axis=0) - dv / LSB_V) <= 1.0 + 1e-6)


def test_malformed_logs_name_the_file_and_the_line(tmp_path):
    src = tmp_path / "imu.txt"
    _kfgins_file(src, n=50)
    lines = src.read_text().splitlines()
    lines[20] = lines[20].replace(lines[20].split()[3], "abc")
    src.write_text("\n".join(lines) + "\n")
    r = bench("replay", "--imu-log", str(src), "--estimator", "decode_only", "-o", "o.mcap", "-q", cwd=tmp_path,
              expect=2)
    assert str(src) in r.err and "line 21" in r.err and "column 4" in r.err, r.err
    # times that go back
    _kfgins_file(src, n=50)
    lines = src.read_text().splitlines()
    lines[30], lines[31] = lines[31], lines[30]
    src.write_text("\n".join(lines) + "\n")
    r = bench("replay", "--imu-log", str(src), "--estimator", "decode_only", "-o", "o.mcap", "-q", cwd=tmp_path,
              expect=2)
    assert str(src) in r.err and "line 32" in r.err and "not later" in r.err, r.err
    # a PSINS sample that is no number: its line in the file
    text = PSINS.read_text().splitlines()
    first = next(i for i, ln in enumerate(text) if ln.strip() and not ln.startswith("%")) + 3  # after 3 parameter lines
    bad = tmp_path / "bad.imu"
    bad.write_text("\n".join([*text[:first + 10], "1 2 x 4 5 6", *text[first + 10:first + 300]]) + "\n")
    r = bench("replay", "--imu-log", str(bad), "--estimator", "decode_only", "-o", "o.mcap", "-q", cwd=tmp_path,
              expect=2)
    assert str(bad) in r.err and f"line {first + 11}:" in r.err and "'1 2 x 4 5 6'" in r.err, r.err
    # a declaration with a unit the bench does not know names the key
    log = tmp_path / "d.csv"
    log.write_text("0,1,2,3,4,5,6\n")
    (tmp_path / "d.toml").write_text('columns = ["t","a","b","c","d","e","f"]\ntime_column = "t"\ntime_unit = "s"\n'
                                     'gyro_columns = ["a","b","c"]\ngyro_unit = "furlong"\n'
                                     'accel_columns = ["d","e","f"]\naccel_unit = "m/s"\n')
    r = bench("replay", "--imu-log", str(log), "--estimator", "decode_only", "-o", "o.mcap", "-q", cwd=tmp_path,
              expect=2)
    assert "d.toml" in r.err and "gyro_unit" in r.err and "furlong" in r.err, r.err


# ----------------------------------------------------------------------------- rows
def test_row_the_formats_engineers_have_are_replayed_not_refused(tmp_path):
    """57b1bce: each refused with exit 2 ("no ICD IMU frame ...; found text" / "no NMEA
    sentence"). Now each is replayed (exit 0) with one ICD frame per sample on the line."""
    kf = tmp_path / "imu.txt"
    rows = _kfgins_file(kf, n=400)
    sim = tmp_path / "sim"
    _gnss_ins_sim(sim, n=401)
    pos = tmp_path / "gnss.pos"
    pos.write_text("".join(f"{345_600 + k}.000000000 34.24605 108.90965 380.0 1.0 1.0 2.0\n" for k in range(1, 3)))
    for name, args, frames in [
        ("psins", ["--imu-log", str(PSINS), "--epoch", "2014-03-21T09:00:00Z"], 60_000),
        ("kfgins", ["--imu-log", str(kf), "--gnss-log", str(pos), "--gps-week", "1785"], len(rows)),
        ("gnss-ins-sim", ["--imu-log", str(sim), "--epoch", "2024-01-01T00:00:00Z"], 400),
    ]:
        out = tmp_path / f"{name}.mcap"
        r = bench("replay", *args, "--estimator", "decode_only", "--step", "20", "-o", str(out), "-q", cwd=tmp_path)
        assert r.code == 0, (name, r.text)
        figures = _run_start(out)
        assert json.loads(figures["log_figures"])["imu"]["frames"] == frames, name
        assert figures["imu_format"] == name, figures["imu_format"]
    figures = _run_start(tmp_path / "kfgins.mcap")
    assert figures["gnss_format"] == "kfgins" and json.loads(figures["log_figures"])["gnss"]["epochs"] == 2


def test_row_a_file_of_no_known_format_says_which_formats_exist_and_how_to_declare_one(tmp_path):
    """57b1bce: "no ICD IMU frame ...; found text" and nothing on what to do."""
    src = tmp_path / "mystery.log"
    src.write_text("ax=1 ay=2 az=3\nax=1 ay=2 az=3\n")
    r = bench("replay", "--imu-log", str(src), "--estimator", "decode_only", "-o", "o.mcap", "-q", cwd=tmp_path,
              expect=2)
    for word in (str(src), "psins", "kfgins", "gnss-ins-sim", "declare", "--imu-format", "docs/exchange.md"):
        assert word in r.err, (word, r.err)


def _run_start(recording: Path) -> dict:
    from bench.record.mcap_io import RecordingReader

    with RecordingReader(recording) as r:
        return dict(r.metadata()["run_start"])


def _static_icd(path: Path, seconds: int = 30, rate: int = 100) -> None:
    """A level IMU at rest facing north at 30 deg N, as ICD bytes (built here: no bench encoder)."""
    n = seconds * rate
    g, w = 9.7933, 7.292115e-5
    lat = math.radians(30.0)
    dth = np.tile(np.rint(np.array([0.0, w * math.cos(lat), w * math.sin(lat)]) / rate / LSB_TH), (n, 1))
    dv = np.tile(np.rint(np.array([0.0, 0.0, g]) / rate / LSB_V), (n, 1))
    path.write_bytes(encode_icd(np.arange(1, n + 1) * (1_000_000 // rate), dth, dv))


def test_row_score_of_a_field_log_replay_with_truth_judges_it_or_says_how(tmp_path):
    """57b1bce: `bench score` of an --estimator replay with --truth exited 3 ("no test case
    attached"), and so did a --case replay. Now a --case replay carries its case and is
    judged (exit 0 or 1); an --estimator replay exits 2 saying how to give the criteria,
    and with --case it is judged."""
    imu = tmp_path / "imu.bin"
    _static_icd(imu, rate=200)  # the case's synthetic drive declares 200 Hz (a replay at another rate is refused)
    truth = tmp_path / "truth.csv"
    truth.write_text("t,lat,lon,h,heading,pitch,roll\n" + "".join(f"{k},30.0,110.0,50.0,0,0,0\n" for k in range(31)))
    case = tmp_path / "case.toml"
    (tmp_path / "drive.toml").write_text((HERE.parent / "data" / "short_drive.toml").read_text())
    case.write_text('[case]\nid = "FL"\ntitle = "field log"\nrequirements = ["R"]\n[scenario]\nscript = "drive.toml"\n'
                    '[dut]\nkind = "in_process"\nname = "decode_only"\n[[criterion]]\nid = "H"\nrequirement = "R"\n'
                    'metric = "output.missing_fraction"\nat_most = "100 %"\n')
    common = ["--imu-log", str(imu), "--truth", str(truth), "--truth-format", "csv", "--epoch",
              "2026-01-05T00:00:00Z", "-q"]
    bench("replay", *common, "--estimator", "decode_only", "-o", "est.mcap", cwd=tmp_path, expect=0)
    r = bench("score", "est.mcap", cwd=tmp_path)
    assert r.code == 2, r.text
    assert "est.mcap" in r.err and "--case" in r.err and "criteria" in r.err, r.err
    r = bench("score", "est.mcap", "--case", str(case), cwd=tmp_path)
    assert r.code in (0, 1) and "FL" in r.out, r.text
    bench("replay", *common, "--case", str(case), "-o", "case.mcap", cwd=tmp_path, expect=0)
    r = bench("score", "case.mcap", cwd=tmp_path)
    assert r.code in (0, 1) and "FL" in r.out, r.text


def test_row_a_log_without_a_date_is_not_dated_silently(tmp_path):
    """57b1bce: without --epoch a PSINS log was dated 2025-06-01 without a word. Now the
    replay warns, naming the assumed epoch, and run_start says it was assumed."""
    r = bench("replay", "--imu-log", str(PSINS), "--estimator", "decode_only", "--step", "20", "-o", "p.mcap",
              cwd=tmp_path, expect=0)
    assert "WARNING" in r.err and "ASSUMED" in r.err and "2025-06-01" in r.err and "--epoch" in r.err, r.err
    assert _run_start(tmp_path / "p.mcap")["epoch_source"].startswith("ASSUMED")
    r = bench("replay", "--imu-log", str(PSINS), "--estimator", "decode_only", "--step", "20", "--epoch",
              "2014-03-21T09:00:00Z", "-o", "q.mcap", cwd=tmp_path, expect=0)
    assert "WARNING" not in r.err, r.err


def test_row_allan_does_not_call_the_psins_scale_constant_gravity(tmp_path):
    """57b1bce: "mean specific force 9.7955 m/s^2 (gravity 9.7803)": 9.780327 is the g of
    the header's ug*s LSB unit, not the gravity of the log's place (34.25 deg N, 380 m:
    9.7955). Now the specific force is compared with the normal gravity there and the
    constant is named for what it is."""
    r = bench("imu", "allan", str(PSINS), cwd=tmp_path, expect=0)
    assert "(gravity 9.7803)" not in r.out, r.out
    head = r.out.splitlines()[1]
    assert "expected 9.795" in head and "normal gravity at the log's latitude 34.2460 deg, height 380 m" in head, head
    assert "accelerometer LSB unit: ug*s of g = 9.780327" in r.out


def test_row_allan_reads_the_other_formats(tmp_path):
    """57b1bce: a KF-GINS imu.txt was "not a PSINS IMU log"."""
    src = tmp_path / "imu.txt"
    _kfgins_file(src, n=3000)
    r = bench("imu", "allan", str(src), cwd=tmp_path, expect=0)
    assert "3000 samples at 200 Hz" in r.out, r.out


# ----------------------------------------------------------------------------- the i2Nav round trip
@pytest.fixture(scope="module")
def original(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("orig")
    bench("run", str(CASE), "-o", str(out), "-q", "--no-plots", cwd=out, expect=1)
    return out / "recordings" / "XCH-LOGS" / "XCH-LOGS-s1.mcap"


def test_export_then_replay_of_the_i2nav_files_gives_the_same_verdicts(original, tmp_path):
    """`bench export --format i2nav` of a run, then `bench replay --imu-log imu.txt
    --gnss-log gnss.pos --truth truth.nav --case` of the files: every criterion gets the
    same verdict, the epoch comes back from the files' GPS week and seconds, and the IMU
    frames carry the run's increments to the LSB."""
    folder = tmp_path / "x"
    bench("export", str(original), "--format", "i2nav", "-o", str(folder), cwd=tmp_path, expect=0)
    r = bench("replay", "--imu-log", str(folder / "imu.txt"), "--gnss-log", str(folder / "gnss.pos"), "--truth",
              str(folder / "truth.nav"), "--truth-format", "kfgins", "--case", str(CASE), "-o", "back.mcap",
              cwd=tmp_path, expect=0)
    assert "WARNING" not in r.err, r.err
    a = bench("score", str(original), "--json", "a.json", cwd=tmp_path)
    b = bench("score", "back.mcap", "--json", "b.json", cwd=tmp_path)
    assert a.code == b.code == 1  # H-RMS passes, H-RMS-TIGHT fails, on both
    va = {c["id"]: c["verdict"] for c in json.loads((tmp_path / "a.json").read_text())["cases"][0]["criteria"]}
    vb = {c["id"]: c["verdict"] for c in json.loads((tmp_path / "b.json").read_text())["cases"][0]["criteria"]}
    assert va == vb and va["H-RMS"] == "PASS" and va["H-RMS-TIGHT"] == "FAIL", (va, vb)
    s0, s1 = _run_start(original), _run_start(tmp_path / "back.mcap")
    assert s1["epoch_utc_ns"] == s0["epoch_utc_ns"], (s0["epoch_utc_ns"], s1["epoch_utc_ns"], s1["epoch_source"])
    assert "week" in s1["epoch_source"]
    from bench.record.mcap_io import RecordingReader

    with RecordingReader(original) as rd:
        imu = rd.read_columnar("/imu")
    f = decode_icd(_stream(folder / "imu.txt"))
    assert np.array_equal(f["t_us"] * 1000, imu["t_ns"])
    assert np.all(np.abs(f["dth"].sum(axis=0) - imu["dtheta"].sum(axis=0) / LSB_TH) <= 1.0 + 1e-3)
    assert np.all(np.abs(f["dv"].sum(axis=0) - imu["dvel"].sum(axis=0) / LSB_V) <= 1.0 + 1e-3)


def test_seconds_of_week_take_the_week_from_an_option_or_the_truth_or_say_it_is_assumed(tmp_path):
    """GPS seconds of week carry no week: --gps-week, a truth.nav's week column, or --epoch
    (which must agree with the log) date the log; without any the week is assumed, loudly."""
    from bench.errors import ConfigError
    from bench.exchange.field_logs import convert_field_logs

    src = tmp_path / "imu.txt"
    _kfgins_file(src, n=100, sow0=345_600.0)  # Thursday 00:00 GPS of the week
    week = 2350
    # UTC = GPS - 18 s; GPS zero 1980-01-06
    want = (315_964_800 + week * 604_800 + 345_600 - 18) * 10**9
    conv = convert_field_logs(src, None, gps_week=week)
    assert conv.epoch_ns == want and not conv.warnings and "week 2350 (--gps-week)" in conv.epoch_rule
    nav = tmp_path / "truth.nav"
    nav.write_text("".join(f"{week} {345_600 + k * 0.1:.3f} 30.0 110.0 50.0 0 0 0 0 0 90\n" for k in range(10)))
    conv = convert_field_logs(src, None, truth=nav, truth_format="kfgins")
    assert conv.epoch_ns == want and "week column" in conv.epoch_rule
    assert conv.truth is not None and abs(conv.truth.t[0]) < 1e-9  # the truth's first line is bench time zero
    conv = convert_field_logs(src, None)
    assert conv.warnings and "ASSUMED" in conv.warnings[0] and "--gps-week" in conv.warnings[0]
    assert conv.epoch_rule.startswith("the logs' GPS seconds of week with week") and "ASSUMED" in conv.epoch_rule
    ok = convert_field_logs(src, None, epoch_ns=want)
    assert ok.epoch_ns == want and not ok.warnings
    with pytest.raises(ConfigError) as err:
        convert_field_logs(src, None, epoch_ns=want + 3_600 * 10**9, gps_week=week)
    assert "--epoch" in str(err.value) and "--gps-week" in str(err.value)
