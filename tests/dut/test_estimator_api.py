"""The estimator API as a DUT author meets it: every field of a CAN message that did not
arrive, epoch counters filled by the bench, the public names of ``bench.dut``, and
``[dut] name = "package.module:Class"`` -- in process and through the harness."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bench.dut.epochs import EpochNumbering
from bench.dut.estimator import (
    CanView,
    DutInputs,
    Estimator,
    EstimatorOutput,
    create_estimator,
    register_estimator,
)
from bench.errors import ConfigError
from bench.faults.schedule import FaultSchedule
from bench.frames import CanBatch
from bench.record.mcap_io import RecordingReader
from bench.run.engine import run
from bench.run.spec import DutSpec, RunSpec
from bench.scenario.loader import load_scenario
from bench.topics import NAV_QUALITY_DTYPE, NAV_SOLUTION_DTYPE
from bench.wire.can import CanEncoder
from bench.wire.imu import IMU_SAMPLE_DTYPE
from bench.wire.nmea import GNSS_FIX_DTYPE
from bench.wire.receive import BENCH_MESSAGES, BenchTrafficDecoder, empty_columns
from tests.dut.harness_util import drive_harness

SHORT = Path(__file__).parent.parent / "data" / "short_drive.toml"
TABLES = {"imu": {"grade": "navigation", "rate": "200 Hz"}, "doppler": {"model": "seed000"}}  # no odometer, driver

#: One frame of every bench message, as the bench sends it.
_ONE = {
    "BENCH_TIME": {"time_ns": [10_000_000], "lockstep": [1]},
    "BENCH_EPOCH": {"epoch_utc_ns": [1_772_352_000_000_000_000]},
    "BENCH_CMD": {"command": [1]},
    "ODOMETER": {"pulse_count": [7], "speed": [1.5], "reverse": [0], "valid": [1]},
    "DRIVER_INPUT": {"left_lever": [0], "right_lever": [1], "steering": [0.1], "brake": [0]},
    "DOPPLER": {"speed": [2.5], "quality": [200], "valid": [1], "low_signal": [0]},
}


def _spec(out: Path, dut: DutSpec, duration_s: float = 2.0) -> RunSpec:
    return RunSpec(scenario=load_scenario(SHORT), tables=TABLES, schedule=FaultSchedule(), dut=dut, out=out,
                   duration_ns=round(duration_s * 1e9))


# ------------------------------------------------------------ a message that did not arrive
def test_an_absent_message_has_the_decoders_columns_zero_length():
    assert set(_ONE) == set(BENCH_MESSAGES)
    enc = CanEncoder()
    got = BenchTrafficDecoder().feed(CanBatch.concat([enc.encode(n, [0], **v) for n, v in _ONE.items()]))
    inputs = DutInputs(0, np.zeros(0, IMU_SAMPLE_DTYPE), np.zeros(0, GNSS_FIX_DTYPE))  # nothing arrived
    for name in BENCH_MESSAGES:
        real, empty = got[name], inputs.message(name)
        assert list(empty) == list(real), name
        for k, col in real.items():
            assert empty[k].dtype == col.dtype and empty[k].shape == (0, *col.shape[1:]), (name, k)
    assert inputs.odometer["speed"].dtype == np.float64 and len(inputs.odometer["speed"]) == 0
    assert len(inputs.doppler["low_signal"]) == 0 and len(inputs.driver["steering"]) == 0
    assert inputs.commands.dtype == np.int64 and len(inputs.commands) == 0
    empty_columns("ODOMETER")["speed"].resize(3, refcheck=False)  # fresh arrays: writable, not shared
    assert len(empty_columns("ODOMETER")["speed"]) == 0
    with pytest.raises(KeyError, match="not a message the bench sends"):
        inputs.message("NAV_SOLUTION")


def test_a_message_absent_from_a_whole_window_still_has_every_field():
    """CanView over a window that holds DOPPLER only: ODOMETER still has all its fields."""
    enc = CanEncoder()
    cols = BenchTrafficDecoder().feed(enc.encode("DOPPLER", [0], **_ONE["DOPPLER"]))
    view = CanView(cols, {"DOPPLER": 0}, {"DOPPLER": 1})
    inputs = DutInputs(0, np.zeros(0, IMU_SAMPLE_DTYPE), np.zeros(0, GNSS_FIX_DTYPE), view)
    assert inputs.doppler["speed"][0] == pytest.approx(2.5)
    assert set(inputs.odometer) == {"pulse_count", "speed", "reverse", "valid", "alive", "rx_ns"}
    quiet = CanView(cols, {"DOPPLER": 1}, {"DOPPLER": 1})  # in the window, not in this step
    assert set(DutInputs(0, inputs.imu, inputs.gnss, quiet).doppler) == set(inputs.doppler)


def test_canview_columns_are_the_step_slices_of_the_message():
    """CanView.columns: per key what the message's dict of the step holds; None for a message
    not in the window; zero-length for one in the window but not in this step."""
    enc = CanEncoder()
    cols = BenchTrafficDecoder().feed(CanBatch.concat([enc.encode("DOPPLER", [0], **_ONE["DOPPLER"]),
                                                       enc.encode("DOPPLER", [5], **_ONE["DOPPLER"])]))
    cuts = {"DOPPLER": [0, 1, 1, 2]}
    for k, n in enumerate((1, 0, 1)):
        keys = ("rx_ns", "speed", "valid")
        got = CanView.at_step(cols, cuts, k).columns("DOPPLER", keys)
        view = CanView.at_step(cols, cuts, k)
        want = [view["DOPPLER"][key] for key in keys]
        assert [len(c) for c in got] == [n] * 3
        assert all(a.dtype == b.dtype and np.array_equal(a, b) for a, b in zip(got, want, strict=True))
        assert view.columns("DOPPLER", keys)[1] is view["DOPPLER"]["speed"]  # after the dict: its arrays
        assert view.columns("ODOMETER", keys) is None


class _ReadsEverything(Estimator):
    """Reads every CAN message's fields every step, whether it came or not."""

    name = "reads_everything"
    seen: dict[str, int]

    def configure(self, config):
        type(self).seen = {}

    def step(self, inputs):
        for name, field_name in (("ODOMETER", "speed"), ("DRIVER_INPUT", "steering"), ("DOPPLER", "speed"),
                                 ("BENCH_CMD", "command")):
            col = inputs.message(name)[field_name]
            type(self).seen[name] = type(self).seen.get(name, 0) + len(col)
        _ = inputs.odometer["valid"], inputs.driver["brake"], inputs.commands
        sol = np.zeros(1, NAV_SOLUTION_DTYPE)
        sol["t_ns"] = inputs.t_ns
        return EstimatorOutput(sol)


def test_an_estimator_reading_absent_messages_runs_in_process(tmp_path):
    register_estimator(_ReadsEverything.name, _ReadsEverything)
    res = run(_spec(tmp_path / "r.mcap", DutSpec("in_process", name=_ReadsEverything.name)))
    assert res.status == "complete", res.reason
    seen = _ReadsEverything.seen
    assert seen["ODOMETER"] == 0 and seen["DRIVER_INPUT"] == 0  # not in the case: never arrived
    assert seen["DOPPLER"] == 100  # 50 Hz for 2 s


def test_an_estimator_reading_absent_messages_runs_through_the_harness():
    register_estimator(_ReadsEverything.name, _ReadsEverything)
    done = drive_harness(_ReadsEverything.name, {}, 5)
    assert done.error is None
    assert len(done.nav.solutions) == 5 and len(done.nav.ready_ns) == 5


# ----------------------------------------------------------------- the bench numbers epochs
class _WrongCounters(Estimator):
    """Sets every epoch counter to 7 (and its qualities' to 9): the bench overwrites them."""

    name = "wrong_counters"

    def step(self, inputs):
        if inputs.t_ns % 20_000_000:  # an epoch every other step, two at once
            return EstimatorOutput()
        t = np.array([inputs.t_ns - 10_000_000, inputs.t_ns]) if inputs.t_ns else np.array([0])
        sol = np.zeros(len(t), NAV_SOLUTION_DTYPE)
        sol["t_ns"], sol["epoch"], sol["rx_ns"] = t, 7, 12345
        q = np.zeros(len(t), NAV_QUALITY_DTYPE)
        q["t_ns"], q["epoch"], q["sigma_pos"] = t, 9, 1.0
        return EstimatorOutput(sol, q)


def _check_numbered(sol: np.ndarray, q: np.ndarray) -> None:
    assert len(sol) > 3
    np.testing.assert_array_equal(sol["epoch"], np.arange(len(sol)) % 256)
    by_time = dict(zip(sol["t_ns"].tolist(), sol["epoch"].tolist(), strict=True))
    assert [by_time[t] for t in q["t_ns"].tolist()] == q["epoch"].tolist()


def test_the_bench_numbers_the_epochs_of_an_in_process_estimator(tmp_path):
    register_estimator(_WrongCounters.name, _WrongCounters)
    res = run(_spec(tmp_path / "e.mcap", DutSpec("in_process", name=_WrongCounters.name), duration_s=3.0))
    assert res.status == "complete", res.reason
    r = RecordingReader(res.path)
    sol, q = r.read_columnar("/dut/nav_solution"), r.read_columnar("/dut/nav_quality")
    assert len(sol) == 301
    _check_numbered(sol, q)
    assert np.all(sol["rx_ns"] >= sol["t_ns"]) and not np.any(sol["rx_ns"] == 12345)
    bad = [d for _, d in r.iter_json("/dut/bad_frames")]  # no counter or pairing fault seen by the bench
    assert bad == [], bad[:3]


def test_the_harness_numbers_the_epochs_as_the_bench_does():
    register_estimator(_WrongCounters.name, _WrongCounters)
    done = drive_harness(_WrongCounters.name, {}, 9)
    assert done.error is None, done.error
    _check_numbered(done.nav.solutions, done.nav.qualities)
    assert "pairing" not in done.rejected and "counter" not in done.rejected, done.rejected


def test_epoch_numbering_wraps_and_pairs_a_quality_one_call_late():
    num = EpochNumbering()
    sol = np.zeros(300, NAV_SOLUTION_DTYPE)
    sol["t_ns"] = np.arange(300) * 10
    num.number(sol, None)
    assert sol["epoch"][255] == 255 and sol["epoch"][256] == 0 and num.next == 300 % 256
    q = np.zeros(3, NAV_QUALITY_DTYPE)
    q["t_ns"], q["epoch"] = [2990, 2980, 5], 200  # two of the last call's, one with no solution
    num.number(None, q)
    assert q["epoch"].tolist() == [299 % 256, 298 % 256, 200]  # unmatched: left as it was


# ------------------------------------------------------------------------ bench.dut names
def test_bench_dut_exports_the_interface_the_dtypes_and_the_icd_values():
    import bench.dut as dut
    from bench import topics
    from bench.dut import (  # one import for a DUT author
        CMD_RESET_FILTER,
        FAULT_BDS,
        FAULT_DOPPLER,
        FAULT_IMU,
        FAULT_ODOMETER,
        FRAME_GRID,
        GNSS_FIX_DTYPE,
        IMU_SAMPLE_DTYPE,
        MODE_DOPPLER,
        MODE_MULTI_SENSOR,
        NAV_QUALITY_DTYPE,
        NAV_SOLUTION_DTYPE,
        ODO_FAULT_VERTICAL,
        SOLUTION_VALID,
        DutInputs,
        Estimator,
        EstimatorOutput,
    )
    from bench.dut import estimator as est_mod
    from bench.wire import icd
    from bench.wire import imu as imu_mod

    assert Estimator is est_mod.Estimator and EstimatorOutput is est_mod.EstimatorOutput
    assert DutInputs is est_mod.DutInputs
    assert NAV_SOLUTION_DTYPE is topics.NAV_SOLUTION_DTYPE and IMU_SAMPLE_DTYPE is imu_mod.IMU_SAMPLE_DTYPE
    assert NAV_QUALITY_DTYPE.names and GNSS_FIX_DTYPE.names
    assert (FRAME_GRID, MODE_DOPPLER, MODE_MULTI_SENSOR, SOLUTION_VALID, CMD_RESET_FILTER) == (1, 2, 5, 1, 3)
    assert (FAULT_ODOMETER, FAULT_DOPPLER, FAULT_BDS, FAULT_IMU, ODO_FAULT_VERTICAL) == (1, 2, 4, 8, 3)
    assert set(icd.__all__) <= set(dut.__all__) and all(getattr(dut, n) is getattr(icd, n) for n in icd.__all__)
    assert set(dut.__all__) <= set(dir(dut))
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        _ = dut.nope


def test_the_icd_values_are_the_dbcs():
    """Each named value against the DBC's value table or signal comment."""
    from bench.wire import icd
    from bench.wire.dbc import database, spec
    from bench.wire.quantities import QUANTITIES

    assert spec("BENCH_CMD").signal("Command").choices == {
        icd.CMD_SWITCH_TO_GRID: "SwitchToGrid", icd.CMD_SWITCH_TO_GEOGRAPHIC: "SwitchToGeographic",
        icd.CMD_RESET_FILTER: "ResetFilter"}
    nav = database().get_message_by_name("NAV_SOLUTION")
    mode_text = nav.get_signal_by_name("Mode").comment
    assert mode_text == ", ".join(f"{v} {n}" for v, n in sorted(icd.MODE_NAMES.items())) + "."
    modes = [icd.MODE_ALIGNING, icd.MODE_INERTIAL, icd.MODE_DOPPLER, icd.MODE_ODOMETER, icd.MODE_BDS,
             icd.MODE_MULTI_SENSOR]
    assert modes == sorted(icd.MODE_NAMES)
    assert f"{icd.FRAME_GEOGRAPHIC} geographic, {icd.FRAME_GRID} grid" in nav.get_signal_by_name("NavFrame").comment
    valid = spec("NAV_SOLUTION").signal("SolutionValid")
    assert (valid.minimum, valid.maximum) == (icd.SOLUTION_INVALID, icd.SOLUTION_VALID)
    bits = next(q for q in QUANTITIES["NAV_QUALITY"] if q.name == "fault_detected").signals
    assert [1 << bits.index(f"Fault{s}") for s in ("Odometer", "Doppler", "Bds", "Imu")] == [
        icd.FAULT_ODOMETER, icd.FAULT_DOPPLER, icd.FAULT_BDS, icd.FAULT_IMU]
    cls = database().get_message_by_name("NAV_QUALITY").get_signal_by_name("OdoFaultClass").comment
    for value, word in ((icd.ODO_FAULT_NONE, "none"), (icd.ODO_FAULT_LONGITUDINAL, "longitudinal"),
                        (icd.ODO_FAULT_LATERAL, "lateral"), (icd.ODO_FAULT_VERTICAL, "vertical")):
        assert f"{value} {word}" in cls
    assert spec("NAV_SOLUTION").signal("EpochCounter").field.length == 8 and icd.EPOCH_MODULUS == 256
    from bench.run.traffic import COMMAND_CODES

    assert COMMAND_CODES == {"grid": icd.CMD_SWITCH_TO_GRID, "geographic": icd.CMD_SWITCH_TO_GEOGRAPHIC,
                             "reset": icd.CMD_RESET_FILTER}


def test_importing_bench_dut_loads_nothing_heavy():
    code = ("import sys, bench.dut; heavy = [m for m in ('numpy', 'numba', 'cantools', 'bench.dut.estimator', "
            "'bench.wire.imu') if m in sys.modules]; print(heavy); from bench.dut import MODE_BDS; print(MODE_BDS)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.split("\n")[:2] == ["[]", "4"], out


# ------------------------------------------------------------- [dut] name = "module:Class"
_MODULE = '''
import numpy as np
from bench.dut import Estimator, EstimatorOutput, NAV_SOLUTION_DTYPE

class Mine(Estimator):
    def configure(self, config):
        self.tag = config.get("tag", "{tag}")

    def step(self, inputs):
        sol = np.zeros(1, NAV_SOLUTION_DTYPE)
        sol["t_ns"], sol["h"] = inputs.t_ns, {height}
        return EstimatorOutput(sol)

def make():
    return Mine()

def not_one():
    return object()

class NotAnEstimator:
    pass

class Abstract(Estimator):
    pass

VALUE = 3
'''


def _module(folder: Path, name: str, tag: str = "a", height: float = 1.0) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{name}.py").write_text(_MODULE.format(tag=tag, height=height))
    return folder


def test_a_module_class_name_makes_the_estimator_from_beside_the_case(tmp_path):
    a = _module(tmp_path / "a", "apimod_one", tag="a")
    est = create_estimator("apimod_one:Mine", {}, search=[a])
    assert type(est).__name__ == "Mine" and est.tag == "a" and est.name == "apimod_one:Mine"
    assert create_estimator("apimod_one:make", {"tag": "z"}, search=[a]).tag == "z"  # a factory
    # a module of the same name beside another case is that case's
    b = _module(tmp_path / "b", "apimod_one", tag="b")
    assert create_estimator("apimod_one:Mine", {}, search=[b]).tag == "b"
    assert create_estimator("apimod_one:Mine", {}, search=[a]).tag == "a"
    pkg = tmp_path / "c" / "apipkg"
    _module(pkg, "inner", tag="pkg")
    (pkg / "__init__.py").write_text("")
    assert create_estimator("apipkg.inner:Mine", {}, search=[tmp_path / "c"]).tag == "pkg"  # a package
    assert create_estimator("bench.estimators.basic:DecodeOnly").name == "decode_only"  # the Python path


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("apimod_absent:Mine", "no module 'apimod_absent'"),
        ("apimod_two.sub:Mine", "no module 'apimod_two.sub'"),
        ("apimod_two:Nope", "has no 'Nope'"),
        ("apimod_two:NotAnEstimator", "not a subclass of bench.dut.Estimator"),
        ("apimod_two:Abstract", "abstract class: it does not implement step"),
        ("apimod_two:VALUE", "is a int, not an Estimator subclass or a factory"),
        ("apimod_two:not_one", "made a builtins.object, not a bench.dut.Estimator"),
        ("apimod_two:", "expected package.module:Class"),
        ("apimod two:Mine", "expected package.module:Class"),
        ("json:JSONDecoder", "not a subclass"),
    ],
)
def test_a_module_class_name_that_names_no_estimator_is_a_config_error(tmp_path, name, expected):
    folder = _module(tmp_path, "apimod_two")
    with pytest.raises(ConfigError, match=expected) as err:
        create_estimator(name, {}, search=[folder])
    assert err.value.key == "dut.name"


def test_a_module_beside_the_case_with_an_installed_modules_name_is_refused(tmp_path):
    (tmp_path / "json.py").write_text("X = 1\n")
    with pytest.raises(ConfigError, match="has the name of one already imported") as err:
        create_estimator("json:X", {}, search=[tmp_path])
    assert err.value.key == "dut.name"


def test_a_module_whose_own_import_fails_is_the_estimator_failing_to_start(tmp_path):
    (tmp_path / "apimod_broken.py").write_text("import apimod_not_installed_anywhere\n")
    with pytest.raises(ModuleNotFoundError, match="apimod_not_installed_anywhere"):
        create_estimator("apimod_broken:Mine", {}, search=[tmp_path])
    spec = _spec(tmp_path / "broken.mcap", DutSpec("in_process", name="apimod_broken:Mine", cwd=tmp_path))
    res = run(spec)
    assert res.status == "dut_failed" and "failed to start: ModuleNotFoundError" in res.reason


def test_a_module_class_name_runs_in_process_from_the_case_folder(tmp_path):
    _module(tmp_path, "apimod_run", height=42.0)
    res = run(_spec(tmp_path / "m.mcap", DutSpec("in_process", name="apimod_run:Mine", cwd=tmp_path)))
    assert res.status == "complete", res.reason
    sol = RecordingReader(res.path).read_columnar("/dut/nav_solution")
    assert len(sol) == 201 and np.all(sol["h"] == 42.0)


def test_the_harness_takes_a_module_class_name_from_its_working_directory(tmp_path):
    _module(tmp_path, "apimod_harness", height=7.0)
    sys.path.insert(0, str(tmp_path))  # what python -m does with the working directory
    try:
        done = drive_harness("apimod_harness:Mine", {}, 4)
    finally:
        sys.path.remove(str(tmp_path))
    assert done.error is None and np.all(done.nav.solutions["h"] == 7.0) and len(done.nav.solutions) == 4


def test_the_harness_command_refuses_a_name_that_names_no_estimator(tmp_path):
    _module(tmp_path, "apimod_cli")
    r = subprocess.run([sys.executable, "-m", "bench.dut.harness", "--estimator", "apimod_cli:Nope", "--imu",
                        "/dev/null", "--gnss", "/dev/null"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("harness: --estimator apimod_cli:Nope: dut.name: the module 'apimod_cli'"), r.stderr
    assert "has no 'Nope'" in last and "Traceback" not in r.stderr
