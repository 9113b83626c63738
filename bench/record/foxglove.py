"""Foxglove well-known schemas (JSON encoding), so recordings open in Foxglove Studio
with a map (LocationFix) and 3-D/plot panels (PoseInFrame)."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

__all__ = ["LOCATION_FIX", "POSE_IN_FRAME", "location_fixes", "poses_in_frame", "location_fix_json", "pose_json"]

_TIME = {
    "type": "object",
    "title": "time",
    "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0}},
}

LOCATION_FIX: dict[str, Any] = {
    "title": "foxglove.LocationFix",
    "description": "A navigation satellite fix for any Global Navigation Satellite System",
    "type": "object",
    "properties": {
        "timestamp": _TIME,
        "frame_id": {"type": "string"},
        "latitude": {"type": "number", "description": "Latitude in degrees"},
        "longitude": {"type": "number", "description": "Longitude in degrees"},
        "altitude": {"type": "number", "description": "Altitude in meters"},
        "position_covariance": {"type": "array", "items": {"type": "number"}, "minItems": 9, "maxItems": 9},
        "position_covariance_type": {"type": "integer", "enum": [0, 1, 2, 3]},
    },
}

_VEC3 = {"type": "object", "properties": {k: {"type": "number"} for k in "xyz"}}
_QUAT = {"type": "object", "properties": {k: {"type": "number"} for k in "xyzw"}}

POSE_IN_FRAME: dict[str, Any] = {
    "title": "foxglove.PoseInFrame",
    "description": "A timestamped pose for an object or reference frame in 3D space",
    "type": "object",
    "properties": {
        "timestamp": _TIME,
        "frame_id": {"type": "string"},
        "pose": {"type": "object", "properties": {"position": _VEC3, "orientation": _QUAT}},
    },
}


def _stamp(utc_ns: int) -> dict[str, int]:
    return {"sec": int(utc_ns // 1_000_000_000), "nsec": int(utc_ns % 1_000_000_000)}


def location_fixes(
    epoch_ns: int,
    t_ns: np.ndarray,
    lat: np.ndarray,
    lon: np.ndarray,
    h: np.ndarray,
    sigma_enu: np.ndarray | None = None,
    frame_id: str = "truth",
) -> list[dict[str, Any]]:
    """LocationFix documents (lat, lon in rad; optional 1-sigma ENU, m)."""
    out = []
    for i in range(len(t_ns)):
        cov = [0.0] * 9
        ctype = 0
        if sigma_enu is not None:
            cov[0], cov[4], cov[8] = (float(s) ** 2 for s in sigma_enu[i])
            ctype = 2
        out.append(
            {
                "timestamp": _stamp(epoch_ns + int(t_ns[i])),
                "frame_id": frame_id,
                "latitude": math.degrees(float(lat[i])),
                "longitude": math.degrees(float(lon[i])),
                "altitude": float(h[i]),
                "position_covariance": cov,
                "position_covariance_type": ctype,
            }
        )
    return out


def poses_in_frame(
    epoch_ns: int, t_ns: np.ndarray, enu: np.ndarray, q_bn: np.ndarray, frame_id: str = "enu"
) -> list[dict[str, Any]]:
    """PoseInFrame documents: position in a local ENU frame (m), orientation q_bn."""
    out = []
    for i in range(len(t_ns)):
        q = q_bn[i]
        out.append(
            {
                "timestamp": _stamp(epoch_ns + int(t_ns[i])),
                "frame_id": frame_id,
                "pose": {
                    "position": {"x": float(enu[i, 0]), "y": float(enu[i, 1]), "z": float(enu[i, 2])},
                    "orientation": {"x": float(q[1]), "y": float(q[2]), "z": float(q[3]), "w": float(q[0])},
                },
            }
        )
    return out


def _num(x: float) -> str:
    """A float as ``json.dumps`` writes it."""
    if math.isfinite(x):
        return repr(x)
    return "NaN" if x != x else ("Infinity" if x > 0 else "-Infinity")


def location_fix_json(
    epoch_ns: int,
    t_ns: np.ndarray,
    lat: np.ndarray,
    lon: np.ndarray,
    h: np.ndarray,
    frame_id: str = "truth",
) -> list[bytes]:
    """:func:`location_fixes` without covariance, encoded: the bytes of ``json.dumps(doc,
    separators=(",", ":"))`` of each document, formatted directly (the display topics' hot
    path: a dict and the encoder per message cost more than the message)."""
    head = '{"timestamp":{"sec":%d,"nsec":%d},"frame_id":' + json.dumps(frame_id) + ',"latitude":'
    tail = ',"position_covariance":[0.0,0.0,0.0,0.0,0.0,0.0,0.0,0.0,0.0],"position_covariance_type":0}'
    utc = (int(epoch_ns) + np.asarray(t_ns, dtype=np.int64)).tolist()
    la, lo, al = np.degrees(lat).tolist(), np.degrees(lon).tolist(), np.asarray(h, dtype=float).tolist()
    return [(head % (u // 1_000_000_000, u % 1_000_000_000) + _num(a) + ',"longitude":' + _num(b)
             + ',"altitude":' + _num(c) + tail).encode() for u, a, b, c in zip(utc, la, lo, al, strict=True)]


def pose_json(epoch_ns: int, t_ns: np.ndarray, enu: np.ndarray, q_bn: np.ndarray, frame_id: str = "enu") -> list[bytes]:
    """:func:`poses_in_frame` encoded, as :func:`location_fix_json`."""
    head = '{"timestamp":{"sec":%d,"nsec":%d},"frame_id":' + json.dumps(frame_id) + ',"pose":{"position":{"x":'
    utc = (int(epoch_ns) + np.asarray(t_ns, dtype=np.int64)).tolist()
    p, q = np.asarray(enu, dtype=float).tolist(), np.asarray(q_bn, dtype=float).tolist()
    return [(head % (u // 1_000_000_000, u % 1_000_000_000) + _num(e[0]) + ',"y":' + _num(e[1]) + ',"z":' + _num(e[2])
             + '},"orientation":{"x":' + _num(r[1]) + ',"y":' + _num(r[2]) + ',"z":' + _num(r[3]) + ',"w":'
             + _num(r[0]) + "}}}").encode() for u, e, r in zip(utc, p, q, strict=True)]
