"""The DUT side of the bench: the estimator interface and everything a DUT author needs.

One import::

    from bench.dut import Estimator, EstimatorOutput, DutInputs, NAV_SOLUTION_DTYPE, MODE_DOPPLER

gives the interface (:class:`~bench.dut.estimator.Estimator`,
:class:`~bench.dut.estimator.EstimatorOutput`, :class:`~bench.dut.estimator.DutInputs`,
:func:`~bench.dut.estimator.register_estimator`), the record dtypes (NAV_SOLUTION and
NAV_QUALITY records to return, the IMU samples and GNSS fixes handed over) and the ICD's
named values (:mod:`bench.wire.icd`: frames, modes, the valid bit, fault bits, odometer
fault classes, BENCH_CMD codes). The names are looked up when first used, so importing
this package loads nothing heavy (the harness and the process wrapper live in
:mod:`bench.dut.harness` and :mod:`bench.dut.process`). docs/estimators.md, "Writing your
own estimator".
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from bench.wire import icd as _icd

if TYPE_CHECKING:  # for readers and type checkers; at run time the names load on first use
    from bench.dut.estimator import DutInputs as DutInputs
    from bench.dut.estimator import Estimator as Estimator
    from bench.dut.estimator import EstimatorOutput as EstimatorOutput
    from bench.dut.estimator import create_estimator as create_estimator
    from bench.dut.estimator import known_estimators as known_estimators
    from bench.dut.estimator import register_estimator as register_estimator
    from bench.topics import NAV_QUALITY_DTYPE as NAV_QUALITY_DTYPE
    from bench.topics import NAV_SOLUTION_DTYPE as NAV_SOLUTION_DTYPE
    from bench.wire.icd import *  # noqa: F403
    from bench.wire.imu import IMU_SAMPLE_DTYPE as IMU_SAMPLE_DTYPE
    from bench.wire.nmea import GNSS_FIX_DTYPE as GNSS_FIX_DTYPE

_LAZY = {
    "Estimator": "bench.dut.estimator",
    "EstimatorOutput": "bench.dut.estimator",
    "DutInputs": "bench.dut.estimator",
    "register_estimator": "bench.dut.estimator",
    "create_estimator": "bench.dut.estimator",
    "known_estimators": "bench.dut.estimator",
    "NAV_SOLUTION_DTYPE": "bench.topics",
    "NAV_QUALITY_DTYPE": "bench.topics",
    "IMU_SAMPLE_DTYPE": "bench.wire.imu",
    "GNSS_FIX_DTYPE": "bench.wire.nmea",
}

__all__ = [*_LAZY, *_icd.__all__]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(import_module(_LAZY[name]), name)
    elif name in _icd.__all__:
        value = getattr(_icd, name)
    else:
        raise AttributeError(f"module 'bench.dut' has no attribute {name!r}")
    globals()[name] = value  # looked up once
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
