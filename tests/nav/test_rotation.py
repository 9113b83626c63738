import numpy as np
import pytest

from bench.nav import rotation as r


def _random_euler(rng, n):
    return rng.uniform(0, 2 * np.pi, n), rng.uniform(-1.5, 1.5, n), rng.uniform(-3.1, 3.1, n)


def test_icd_axis_convention():
    # heading 90 deg: the body forward axis (y) points east
    C = r.euler_to_dcm(np.pi / 2, 0.0, 0.0)
    assert pytest.approx([1, 0, 0], abs=1e-15) == C @ [0, 1, 0]
    # pitch up: forward axis gains an up component
    C = r.euler_to_dcm(0.0, 0.1, 0.0)
    assert (C @ [0, 1, 0])[2] == pytest.approx(np.sin(0.1))
    # roll positive: right side (x) down
    C = r.euler_to_dcm(0.0, 0.0, 0.1)
    assert (C @ [1, 0, 0])[2] == pytest.approx(-np.sin(0.1))


def test_euler_dcm_quat_round_trips():
    rng = np.random.default_rng(1)
    psi, th, ga = _random_euler(rng, 500)
    C = r.euler_to_dcm(psi, th, ga)
    assert np.einsum("nij,nkj->nik", C, C) == pytest.approx(np.broadcast_to(np.eye(3), C.shape), abs=1e-14)
    p2, t2, g2 = r.dcm_to_euler(C)
    assert r.wrap_pi(p2 - psi) == pytest.approx(np.zeros(500), abs=1e-12)
    assert t2 == pytest.approx(th, abs=1e-12)
    assert g2 == pytest.approx(ga, abs=1e-12)
    q = r.euler_to_quat(psi, th, ga)
    assert r.quat_to_dcm(q) == pytest.approx(C, abs=1e-14)
    assert r.dcm_to_quat(C) == pytest.approx(q, abs=1e-12)


def test_rotation_vector_round_trip_and_small_angles():
    rng = np.random.default_rng(2)
    phi = rng.normal(size=(200, 3))
    phi *= np.minimum(1.0, 3.0 / np.linalg.norm(phi, axis=1))[:, None]  # angles below pi
    phi[100:] *= 1e-7
    q = r.rotvec_to_quat(phi)
    assert np.linalg.norm(q, axis=1) == pytest.approx(np.ones(200), abs=1e-15)
    assert r.quat_to_rotvec(q) == pytest.approx(phi, rel=1e-9, abs=1e-20)


def test_quaternion_product_composes_rotations():
    rng = np.random.default_rng(3)
    a = r.euler_to_quat(*_random_euler(rng, 50))
    b = r.euler_to_quat(*_random_euler(rng, 50))
    assert r.quat_to_dcm(r.quat_mul(a, b)) == pytest.approx(r.quat_to_dcm(a) @ r.quat_to_dcm(b), abs=1e-14)


def test_omega_nb_b_matches_dcm_derivative():
    rng = np.random.default_rng(4)
    e = np.array(_random_euler(rng, 20)).T
    e[:, 1] = np.clip(e[:, 1], -1.2, 1.2)
    rates = rng.normal(size=(20, 3))
    dt = 1e-6
    Cp = r.euler_to_dcm(*(e + rates * dt).T)
    Cm = r.euler_to_dcm(*(e - rates * dt).T)
    C = r.euler_to_dcm(*e.T)
    Omega = np.einsum("nji,njk->nik", C, (Cp - Cm) / (2 * dt))  # C^T dC/dt
    w = r.euler_rates_to_omega_nb_b(*e.T, *rates.T)
    assert r.skew(w) == pytest.approx(Omega, abs=1e-8)
