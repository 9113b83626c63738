import math

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.paths import models_dir
from bench.sensors.imu.grade import load_grade


@pytest.mark.parametrize("name", sorted(p.stem for p in (models_dir() / "imu").glob("*.toml")))
def test_every_shipped_grade_loads(name):
    g = load_grade(name)
    assert g.name


def test_navigation_grade_values_in_si():
    g = load_grade("navigation")
    assert g.gyro.bias == pytest.approx(np.full(3, math.radians(0.01) / 3600))
    assert g.gyro.noise == pytest.approx(np.full(3, math.radians(0.001) / 60))  # deg/sqrt(h) -> rad/sqrt(s)
    assert g.accel.bias == pytest.approx(np.full(3, 100e-6 * 9.80665))
    assert g.accel.noise == pytest.approx(np.full(3, 10e-6 * 9.80665))  # ug/sqrt(Hz) -> m/s/sqrt(s)
    assert g.gyro.scale_factor == pytest.approx(np.full(3, 5e-6))
    assert g.gyro.quantization == pytest.approx(math.radians(0.1 / 3600))
    assert g.gyro.range == pytest.approx(math.radians(400))
    assert g.accel.range == pytest.approx(20 * 9.80665)


def test_seed000_grade_has_only_the_seed_terms():
    g = load_grade("seed000")
    assert not np.any(g.gyro.scale_factor) and not np.any(g.gyro.misalignment) and g.gyro.quantization == 0


@pytest.mark.parametrize(
    "text,key,words",
    [
        ('[gyro]\nbias = "0.01 m/s"\n', "gyro.bias", "expected angular_rate"),
        ('[gyro]\nbais = "0.01 deg/h"\n', "gyro.bais", "unknown key"),
        ('[accel]\nnoise = "10 ug/sqrt(Hz"\n', "accel.noise", "ends too early"),
        ('[accel]\nbias = ["1 ug", "2 ug"]\n', "accel.bias", "expected 3 values"),
        ('[gyro]\nbias_draw = "sometimes"\n', "gyro.bias_draw", "'fixed' or 'random'"),
        ('[gyro]\nnoise = "-1 deg/sqrt(h)"\n', "gyro.noise", "non-negative"),
        ("colour = 1\n", "colour", "unknown key"),
    ],
)
def test_grade_errors_name_file_and_key(tmp_path, text, key, words):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(ConfigError) as exc:
        load_grade(p)
    assert exc.value.file == str(p) and exc.value.key == key
    assert words in str(exc.value)
