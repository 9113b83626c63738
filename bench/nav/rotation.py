"""Attitude representations: Euler angles (ICD convention), DCMs, quaternions, rotation
vectors. Vectorised over a leading axis.

Euler angles follow ICD 1.0: ``C_bn = Rz(-psi) @ Rx(theta) @ Ry(gamma)`` with heading
``psi`` clockwise from north, pitch ``theta`` nose up, roll ``gamma`` right side down.
Quaternions are scalar first.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "skew",
    "euler_to_dcm",
    "dcm_to_euler",
    "euler_to_quat",
    "quat_to_dcm",
    "dcm_to_quat",
    "quat_to_euler",
    "quat_mul",
    "quat_conj",
    "rotvec_to_quat",
    "quat_to_rotvec",
    "euler_rates_to_omega_nb_b",
    "wrap_pi",
    "wrap_2pi",
]


def wrap_pi(a: np.ndarray | float) -> np.ndarray:
    """Angle(s) wrapped to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def wrap_2pi(a: np.ndarray | float) -> np.ndarray:
    """Angle(s) wrapped to [0, 2 pi)."""
    return np.asarray(a) % (2.0 * np.pi)


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix (..., 3, 3) of vectors (..., 3): ``skew(a) @ b == cross(a, b)``."""
    v = np.asarray(v, dtype=float)
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


def euler_to_dcm(psi: np.ndarray | float, theta: np.ndarray | float, gamma: np.ndarray | float) -> np.ndarray:
    """C_bn (..., 3, 3) from heading, pitch, roll (rad)."""
    sp, cp = np.sin(psi), np.cos(psi)
    st, ct = np.sin(theta), np.cos(theta)
    sg, cg = np.sin(gamma), np.cos(gamma)
    out = np.empty((*np.shape(sp * st * sg), 3, 3))
    out[..., 0, 0] = cp * cg + sp * st * sg
    out[..., 0, 1] = sp * ct
    out[..., 0, 2] = cp * sg - sp * st * cg
    out[..., 1, 0] = -sp * cg + cp * st * sg
    out[..., 1, 1] = cp * ct
    out[..., 1, 2] = -sp * sg - cp * st * cg
    out[..., 2, 0] = -ct * sg
    out[..., 2, 1] = st
    out[..., 2, 2] = ct * cg
    return out


def dcm_to_euler(C_bn: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Heading in [0, 2 pi), pitch, roll (rad) from C_bn (..., 3, 3)."""
    theta = np.arcsin(np.clip(C_bn[..., 2, 1], -1.0, 1.0))
    gamma = np.arctan2(-C_bn[..., 2, 0], C_bn[..., 2, 2])
    psi = wrap_2pi(np.arctan2(C_bn[..., 0, 1], C_bn[..., 1, 1]))
    return psi, theta, gamma


def quat_mul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p * q of quaternions (..., 4)."""
    p0, p1, p2, p3 = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    q0, q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
            p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
            p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
            p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0,
        ],
        axis=-1,
    )


def quat_conj(q: np.ndarray) -> np.ndarray:
    """Conjugate of quaternions (..., 4)."""
    return np.asarray(q) * np.array([1.0, -1.0, -1.0, -1.0])


def _axis_quat(angle: np.ndarray, axis: int) -> np.ndarray:
    angle = np.asarray(angle, dtype=float)
    q = np.zeros((*angle.shape, 4))
    q[..., 0] = np.cos(angle / 2.0)
    q[..., 1 + axis] = np.sin(angle / 2.0)
    return q


def euler_to_quat(psi: np.ndarray | float, theta: np.ndarray | float, gamma: np.ndarray | float) -> np.ndarray:
    """q_bn (..., 4) from heading, pitch, roll (rad), scalar first, non-negative scalar."""
    shape = np.shape(np.asarray(psi) * np.asarray(theta) * np.asarray(gamma))
    psi, theta, gamma = (np.broadcast_to(a, shape) for a in (psi, theta, gamma))
    q = quat_mul(quat_mul(_axis_quat(-psi, 2), _axis_quat(theta, 0)), _axis_quat(gamma, 1))
    return np.where(q[..., :1] < 0.0, -q, q)


def quat_to_dcm(q: np.ndarray) -> np.ndarray:
    """Rotation matrix (..., 3, 3) of unit quaternions (..., 4)."""
    q0, q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty((*np.shape(q0), 3, 3))
    out[..., 0, 0] = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
    out[..., 0, 1] = 2.0 * (q1 * q2 - q0 * q3)
    out[..., 0, 2] = 2.0 * (q1 * q3 + q0 * q2)
    out[..., 1, 0] = 2.0 * (q1 * q2 + q0 * q3)
    out[..., 1, 1] = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
    out[..., 1, 2] = 2.0 * (q2 * q3 - q0 * q1)
    out[..., 2, 0] = 2.0 * (q1 * q3 - q0 * q2)
    out[..., 2, 1] = 2.0 * (q2 * q3 + q0 * q1)
    out[..., 2, 2] = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
    return out


def dcm_to_quat(C: np.ndarray) -> np.ndarray:
    """Unit quaternion (..., 4) with non-negative scalar of rotation matrices (..., 3, 3).

    Shepperd's method: the largest of the four squared components picks the formula.
    """
    C = np.asarray(C, dtype=float)
    tr = C[..., 0, 0] + C[..., 1, 1] + C[..., 2, 2]
    cand = np.stack([tr, C[..., 0, 0], C[..., 1, 1], C[..., 2, 2]], axis=-1)
    k = np.argmax(cand, axis=-1)
    q = np.empty((*C.shape[:-2], 4))
    # case 0: scalar largest
    r = np.sqrt(np.maximum(1.0 + tr, 1e-300))
    q0 = np.stack(
        [
            0.5 * r,
            (C[..., 2, 1] - C[..., 1, 2]) / (2 * r),
            (C[..., 0, 2] - C[..., 2, 0]) / (2 * r),
            (C[..., 1, 0] - C[..., 0, 1]) / (2 * r),
        ],
        axis=-1,
    )
    r1 = np.sqrt(np.maximum(1.0 + C[..., 0, 0] - C[..., 1, 1] - C[..., 2, 2], 1e-300))
    q1 = np.stack(
        [
            (C[..., 2, 1] - C[..., 1, 2]) / (2 * r1),
            0.5 * r1,
            (C[..., 0, 1] + C[..., 1, 0]) / (2 * r1),
            (C[..., 0, 2] + C[..., 2, 0]) / (2 * r1),
        ],
        axis=-1,
    )
    r2 = np.sqrt(np.maximum(1.0 - C[..., 0, 0] + C[..., 1, 1] - C[..., 2, 2], 1e-300))
    q2 = np.stack(
        [
            (C[..., 0, 2] - C[..., 2, 0]) / (2 * r2),
            (C[..., 0, 1] + C[..., 1, 0]) / (2 * r2),
            0.5 * r2,
            (C[..., 1, 2] + C[..., 2, 1]) / (2 * r2),
        ],
        axis=-1,
    )
    r3 = np.sqrt(np.maximum(1.0 - C[..., 0, 0] - C[..., 1, 1] + C[..., 2, 2], 1e-300))
    q3 = np.stack(
        [
            (C[..., 1, 0] - C[..., 0, 1]) / (2 * r3),
            (C[..., 0, 2] + C[..., 2, 0]) / (2 * r3),
            (C[..., 1, 2] + C[..., 2, 1]) / (2 * r3),
            0.5 * r3,
        ],
        axis=-1,
    )
    q = np.choose(k[..., None], [q0, q1, q2, q3])
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0.0, -q, q)


def quat_to_euler(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Heading, pitch, roll (rad) of q_bn (..., 4)."""
    return dcm_to_euler(quat_to_dcm(q))


def rotvec_to_quat(phi: np.ndarray) -> np.ndarray:
    """Quaternion (..., 4) of rotation vectors (..., 3); series form near zero."""
    phi = np.asarray(phi, dtype=float)
    a2 = np.sum(phi * phi, axis=-1)
    a = np.sqrt(a2)
    small = a < 1e-4
    # sin(a/2)/a, cos(a/2) with 6th-order series where a is small
    safe = np.where(small, 1.0, a)
    s = np.where(small, 0.5 - a2 / 48.0 + a2 * a2 / 3840.0, np.sin(safe / 2.0) / safe)
    c = np.where(small, 1.0 - a2 / 8.0 + a2 * a2 / 384.0, np.cos(a / 2.0))
    return np.concatenate([c[..., None], phi * s[..., None]], axis=-1)


def quat_to_rotvec(q: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) of unit quaternions (..., 4), angle in [0, pi]."""
    q = np.asarray(q, dtype=float)
    q = np.where(q[..., :1] < 0.0, -q, q)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1)
    angle = 2.0 * np.arctan2(s, q[..., 0])
    small = s < 1e-12
    factor = np.where(small, 2.0 / np.maximum(q[..., 0], 1e-300), angle / np.where(small, 1.0, s))
    return v * factor[..., None]


def euler_rates_to_omega_nb_b(
    psi: np.ndarray,
    theta: np.ndarray,
    gamma: np.ndarray,
    psi_dot: np.ndarray,
    theta_dot: np.ndarray,
    gamma_dot: np.ndarray,
) -> np.ndarray:
    """Body rate relative to n, expressed in b (..., 3), from Euler angles and their rates.

    From ``dC_bn/dt = C_bn skew(omega_nb_b)`` with the ICD rotation order.
    """
    st, ct = np.sin(theta), np.cos(theta)
    sg, cg = np.sin(gamma), np.cos(gamma)
    del psi  # heading does not enter: rotations about the local vertical
    return np.stack(
        [
            cg * theta_dot + sg * ct * psi_dot,
            gamma_dot - st * psi_dot,
            sg * theta_dot - cg * ct * psi_dot,
        ],
        axis=-1,
    )
