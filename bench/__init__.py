"""Hardware-in-the-loop test bench for vehicle navigation estimators.

Conventions (written once, here; every module follows them)
-----------------------------------------------------------
Frames
    ``n``  navigation frame, local level East-North-Up (ENU) at the current position.
    ``b``  body frame, Right-Forward-Up (RFU), origin at the IMU.
    ``m``  odometer frame, RFU at the odometer.
    ``e``  Earth-centred Earth-fixed (ECEF, WGS-84).
    ``i``  inertial frame.
    Names carry their frames: ``vel_n`` is velocity in n, ``C_bn`` is the direction
    cosine matrix that takes a b-frame vector to n (``v_n = C_bn @ v_b``), ``omega_ib_b``
    is the angular rate of b relative to i expressed in b, ``f_b`` the specific force in b.

Attitude
    Heading ``psi`` is the true heading, clockwise from north, in [0, 2 pi); pitch
    ``theta`` nose up positive; roll ``gamma`` right side down positive.
    ``C_bn = Rz(-psi) @ Rx(theta) @ Ry(gamma)`` with ``Rk(a)`` the active rotation by a
    about axis k (ICD 1.0, section 1). Quaternions are scalar first, ``q_bn`` rotates b to
    n: ``v_n = q_bn * v_b * conj(q_bn)``.

Units
    SI inside: metres, seconds, radians, m/s, rad/s, m/s^2. Latitude and longitude are
    radians inside. Degrees, arcminutes, deg/h, ug and the like appear only at the edges:
    in files people write (parsed by :mod:`bench.units`) and in what people read.

Time
    Integer nanoseconds inside (``t_ns``, numpy ``int64``), measured from scenario start
    (bench time zero). Microseconds on the wire. Floating-point seconds only inside
    numerical kernels, relative to scenario start.

Randomness
    Every random draw comes from a seeded :class:`numpy.random.Generator` that is passed
    in; :func:`bench.rng.stream` derives independent named streams from one run seed.
    There is no global random state.

Errors
    :class:`bench.errors.BenchError` is the root; configuration, plant, link, codec and DUT
    errors derive from it. A failing DUT is a FAIL verdict, a failing bench an ERROR.
"""

from __future__ import annotations

__all__ = ["__version__"]

__version__ = "0.1.0"
