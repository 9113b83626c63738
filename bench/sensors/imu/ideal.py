"""Exact IMU increments from a trajectory.

An IMU reports, for each interval ``[t_k-1, t_k]``, the angle increment
``dtheta = integral(omega_ib_b dt)`` and the velocity increment
``dvel = integral(f_b dt)``, both in the (rotating) body frame. These integrals carry the
coning and sculling of the motion, the Earth's rotation, the transport rate, gravity and
the Coriolis acceleration exactly as a real IMU senses them; a strapdown algorithm with
coning and sculling corrections turns them back into the motion.

The integrals are computed by Gauss-Legendre quadrature on each interval, split at the
trajectory's knots (where a derivative of the motion jumps), so they are exact to
rounding for the smooth motion between knots.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from bench.scenario.trajectory import Trajectory, inertial_quantities

__all__ = ["ImuBlock", "ideal_increments", "interval_ns", "count_intervals"]


@dataclass
class ImuBlock:
    """A run of consecutive IMU samples.

    Attributes
    ----------
    t_ns: (N,) int64 end of each integration interval (time of validity), ns.
    dtheta: (N, 3) angle increments about body x, y, z, rad.
    dvel: (N, 3) velocity increments along body x, y, z, m/s.
    status: (N,) uint8 ICD status bits (0-2 gyro valid, 3-5 accel valid, 6 BIT fault,
        7 saturated).
    """

    t_ns: np.ndarray
    dtheta: np.ndarray
    dvel: np.ndarray
    status: np.ndarray

    def __len__(self) -> int:
        return len(self.t_ns)


#: Status of a healthy sample: all six axes valid.
STATUS_OK = 0b0011_1111


def interval_ns(rate_hz: float) -> int:
    """IMU interval in integer nanoseconds; the rate must divide a second exactly."""
    if not 1.0 <= rate_hz <= 10_000.0:
        raise ValueError(f"IMU rate must be within 1..10000 Hz, found {rate_hz}")
    period = 1e9 / rate_hz
    if abs(period - round(period)) > 1e-6:
        raise ValueError(f"IMU rate {rate_hz} Hz does not give a whole number of nanoseconds per sample")
    return round(period)


def count_intervals(traj: Trajectory, rate_hz: float) -> int:
    """Number of whole IMU intervals within the trajectory."""
    return traj.duration_ns // interval_ns(rate_hz)


def ideal_increments(
    traj: Trajectory,
    rate_hz: float = 200.0,
    *,
    chunk_s: float = 30.0,
    nodes: int = 3,
    start_index: int = 0,
    stop_index: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Iterator[ImuBlock]:
    """Yield exact increments for intervals ``start_index + 1 .. stop_index`` in chunks.

    Parameters
    ----------
    traj:
        The motion.
    rate_hz:
        IMU output rate; ``1e9 / rate_hz`` must be a whole number of nanoseconds.
    chunk_s:
        Length of each yielded block, s (bounds the memory used).
    nodes:
        Gauss-Legendre points per piece.
    start_index, stop_index:
        Range of interval indices (interval k ends at ``k * T``); all by default.
    progress:
        Called with (intervals done, intervals total) after each block.
    """
    T_ns = interval_ns(rate_hz)
    total = count_intervals(traj, rate_hz)
    stop = total if stop_index is None else min(stop_index, total)
    per_chunk = max(1, round(chunk_s * rate_hz))
    x, w = np.polynomial.legendre.leggauss(nodes)
    knots = np.asarray(traj.knots(), dtype=float)
    k = start_index
    while k < stop:
        k_end = min(stop, k + per_chunk)
        idx = np.arange(k, k_end + 1, dtype=np.int64)
        bounds = idx * T_ns * 1e-9
        inner = knots[(knots > bounds[0]) & (knots < bounds[-1])]
        # drop knots that coincide with interval boundaries
        if inner.size:
            near = np.abs(bounds[np.searchsorted(bounds, inner).clip(0, len(bounds) - 1)] - inner) < 1e-12
            inner = inner[~near]
        cuts = np.union1d(bounds, inner) if inner.size else bounds
        owner = np.searchsorted(bounds, cuts[:-1], side="right") - 1
        half = 0.5 * np.diff(cuts)
        mid = 0.5 * (cuts[1:] + cuts[:-1])
        tq = (mid[:, None] + half[:, None] * x[None, :]).ravel()
        _, omega_ib_b, f_b, _ = inertial_quantities(traj.kinematics(tq))
        wq = (half[:, None] * w[None, :]).ravel()[:, None]
        piece_dtheta = (omega_ib_b * wq).reshape(len(half), nodes, 3).sum(axis=1)
        piece_dvel = (f_b * wq).reshape(len(half), nodes, 3).sum(axis=1)
        if inner.size:
            starts = np.flatnonzero(np.diff(np.concatenate([[-1], owner])))
            dtheta = np.add.reduceat(piece_dtheta, starts, axis=0)
            dvel = np.add.reduceat(piece_dvel, starts, axis=0)
        else:
            dtheta, dvel = piece_dtheta, piece_dvel
        n = k_end - k
        yield ImuBlock(
            t_ns=idx[1:] * T_ns,
            dtheta=dtheta,
            dvel=dvel,
            status=np.full(n, STATUS_OK, dtype=np.uint8),
        )
        k = k_end
        if progress is not None:
            progress(k - start_index, stop - start_index)
