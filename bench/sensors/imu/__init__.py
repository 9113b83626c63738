"""Laser-gyro strapdown IMU: exact increments, the error model, grades as data."""

from bench.sensors.imu.ideal import ImuBlock, count_intervals, ideal_increments, interval_ns

__all__ = ["ImuBlock", "count_intervals", "ideal_increments", "interval_ns"]
