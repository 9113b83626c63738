"""An independent inertial-frame alignment of a static PSINS IMU log, numpy only.

Written for the tests from the textbook method (nothing imported from the bench: the log
is parsed here from its documented layout, ../shared/data/README.md), so that the bench's
estimators are judged against attitude nobody on the bench computed:

1. the body's attitude change since the start, C_b0^b(t), from the angle increments
   (rotation-vector update per sample; the coning of a parked vehicle is negligible);
2. the specific force integrated in the frozen start body frame b0 (with the sculling term
   1/2 dtheta x dv): v_b0(t);
3. gravity's integral in the navigation frame frozen at the start (i0), which turns with
   the Earth: v_i0(t) = integral of C_n^i0(tau) [0, 0, g] dtau, in closed form;
4. the rotation C_b0^i0 that maps the centred v_b0 series onto the centred v_i0 series
   (least squares, SVD): centring removes the body's unknown velocity at the start and the
   rocking's mean;
5. the attitude at time t: C_b^n(t) = C_i0^n(t) C_b0^i0 C_b^b0(t).

Heading is observable only through the Earth's rotation turning gravity in inertial space,
so the longer the log the better (a 30-minute log gives the heading to about an arcminute
with a navigation-grade gyro).

    python -m tests.independent.inertial_alignment LOG.imu OUT.csv [--every S]

writes the truth track of a parked vehicle (t, lat, lon, h, heading, pitch, roll in
degrees; the header's surveyed point) for ``[scenario] log`` cases (docs/real_logs.md).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

W_IE = 7.292115e-5  # rad/s, WGS-84
ARCSEC = math.pi / 180.0 / 3600.0
UG = 9.80665e-6  # m/s^2 per micro-g (the PSINS header's "ug*s" unit)

__all__ = ["PsinsLog", "read_psins", "align", "euler", "main"]


@dataclass
class PsinsLog:
    """A PSINS SIMU log: increments (N, 3) in rad and m/s (RFU), the interval (s) and the
    header's surveyed point (deg, deg, m)."""

    dtheta: np.ndarray
    dvel: np.ndarray
    dt: float
    lat_deg: float
    lon_deg: float
    h: float


def read_psins(path: str | Path) -> PsinsLog:
    """The log's three parameter lines after the ``%`` header, then six integers per
    sample (angle increments in gyro LSBs of arcsec, velocity increments in LSBs of ug*s)."""
    lines = [ln for ln in Path(path).read_text().splitlines() if ln.strip() and not ln.startswith("%")]
    lat, lon, h, _t0, dt_ms, _g = (float(x) for x in lines[1].split())
    gf = np.array([float(x) for x in lines[2].split()])
    raw = np.array([[int(x) for x in ln.split()] for ln in lines[3:]], dtype=np.int64)
    return PsinsLog(raw[:, :3] * gf[:3] * ARCSEC, raw[:, 3:] * gf[3:] * UG, dt_ms * 1e-3, lat, lon, h)


def _skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _rotvec(r: np.ndarray) -> np.ndarray:
    a = float(np.linalg.norm(r))
    K = _skew(r)
    if a < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + math.sin(a) / a * K + (1.0 - math.cos(a)) / a**2 * K @ K


def euler(C: np.ndarray) -> tuple[float, float, float]:
    """(heading clockwise from north in [0, 2 pi), pitch, roll) of C_b^n (ENU, RFU), rad."""
    return math.atan2(C[0, 1], C[1, 1]) % (2 * math.pi), math.asin(C[2, 1]), math.atan2(-C[2, 0], C[2, 2])


def align(log: PsinsLog, every_s: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Times (K,) s and (K, 3) heading, pitch, roll (rad) every ``every_s`` over the log,
    from the inertial-frame alignment of the whole log (module docstring)."""
    th, dv, dt = log.dtheta, log.dvel, log.dt
    lat = math.radians(log.lat_deg)
    per = max(1, round(every_s / dt))
    C = np.eye(3)
    v = np.zeros(3)
    ts, vb, tc, cb = [], [], [], []
    for k in range(len(th)):
        v = v + C @ (dv[k] + 0.5 * np.cross(th[k], dv[k]))
        C = C @ _rotvec(th[k])
        if (k + 1) % 10 == 0:
            ts.append((k + 1) * dt)
            vb.append(v.copy())
        if (k + 1) % per == 0:
            tc.append((k + 1) * dt)
            cb.append(C.copy())
    t, vbs = np.array(ts), np.array(vb)
    u = np.array([0.0, math.cos(lat), math.sin(lat)])  # the Earth's axis in the frozen ENU frame
    up = np.array([0.0, 0.0, 1.0])
    a = W_IE * t
    # integral of Rot(u, W tau) up dtau (Rodrigues), any constant g scale dropped by the fit's rotation
    vi = (np.outer(np.sin(a) / W_IE, up) + np.outer((1 - np.cos(a)) / W_IE, np.cross(u, up))
          + np.outer(t - np.sin(a) / W_IE, u * (u @ up)))
    U, _, Vt = np.linalg.svd((vi - vi.mean(axis=0)).T @ (vbs - vbs.mean(axis=0)))
    Cib = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    out = [euler(_rotvec(u * W_IE * tk).T @ Cib @ Cb) for tk, Cb in zip(tc, cb, strict=True)]
    return np.array(tc), np.array(out)


def main(argv: list[str] | None = None) -> int:
    """Write the truth track of a parked vehicle from its log (module docstring)."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("log")
    p.add_argument("out")
    p.add_argument("--every", type=float, default=1.0, help="seconds between truth samples")
    args = p.parse_args(argv)
    log = read_psins(args.log)
    t, hpr = align(log, args.every)
    t = np.concatenate([[0.0], t])  # the attitude at the start: the first sample's (parked)
    hpr = np.degrees(np.vstack([hpr[:1], hpr]))
    rows = [f"{tk:.3f},{log.lat_deg:.8f},{log.lon_deg:.8f},{log.h:.3f},{a:.6f},{b:.6f},{c:.6f}\n"
            for tk, (a, b, c) in zip(t, hpr, strict=True)]
    Path(args.out).write_text("t,lat,lon,h,heading,pitch,roll\n" + "".join(rows))
    print(f"{args.out}: {len(rows)} samples over {t[-1]:.0f} s; heading {hpr[:, 0].mean():.4f} deg, "
          f"pitch {hpr[:, 1].mean():.4f} deg, roll {hpr[:, 2].mean():.4f} deg (means)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
