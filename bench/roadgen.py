"""Generate a scenario's road network from its truth track: ``python -m bench.roadgen S001 OUT``.

The route is the truth track's horizontal path sampled every 2 s (shapely-simplified with a
5 cm tolerance), feature ``route``; distractors are parallel streets offset 20 m to the left
and 25 m to the right along every straight stretch of at least 150 m (shortened 30 m at each
end so that they do not touch the route), and a 150 m side road leaving every corner (a
heading change over 45 deg within 20 s) straight on from where the turn starts, in the
direction the vehicle came from.
Deterministic: the same scenario gives the same file (tests/scoring/test_map_network.py).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import shapely

from bench.scenario.loader import load_scenario
from bench.scoring.roadmap import R_EARTH


def _lonlat(lat0: float, lon0: float, xy: np.ndarray) -> list[list[float]]:
    lat = lat0 + xy[:, 1] / R_EARTH
    lon = lon0 + xy[:, 0] / (R_EARTH * math.cos(lat0))
    return [[round(math.degrees(a), 9), round(math.degrees(b), 9)] for a, b in zip(lon, lat, strict=True)]


def network_doc(scenario: str) -> dict:
    """The GeoJSON FeatureCollection of a scenario's route and distractor roads."""
    traj = load_scenario(scenario).trajectory()
    t = np.arange(0.0, traj.duration_ns * 1e-9, 0.5)
    k = traj.kinematics(t)
    lat0, lon0 = float(k.lat[0]), float(k.lon[0])
    xy = np.stack([(k.lon - lon0) * R_EARTH * math.cos(lat0), (k.lat - lat0) * R_EARTH], axis=1)
    moving = np.hypot(k.vel_n[:, 0], k.vel_n[:, 1]) > 0.5
    keep = np.concatenate([[True], np.hypot(*np.diff(xy, axis=0).T) > 0.05])
    route = shapely.simplify(shapely.linestrings(xy[keep]), 0.05)
    feats = [({"id": "route", "role": "route", "max_speed": 16.7}, np.asarray(route.coords))]
    hdg = np.unwrap(k.euler[:, 0])
    straight = moving & (np.abs(np.gradient(hdg, t)) < math.radians(0.5))
    edges = np.flatnonzero(np.diff(np.concatenate([[0], straight.astype(int), [0]])))
    n_par = 0
    for lo, hi in zip(edges[0::2], edges[1::2], strict=True):
        seg = xy[lo:hi]
        length = float(np.sum(np.hypot(*np.diff(seg, axis=0).T))) if len(seg) > 1 else 0.0
        if length < 150.0:
            continue
        line = shapely.linestrings(seg)
        p0 = np.asarray(shapely.line_interpolate_point(line, 30.0).coords)[0]
        p1 = np.asarray(shapely.line_interpolate_point(line, length - 30.0).coords)[0]
        u = (p1 - p0) / np.hypot(*(p1 - p0))
        left = np.array([-u[1], u[0]])
        for off in (20.0, -25.0):
            n_par += 1
            feats.append(({"id": f"parallel{n_par}", "role": "distractor"}, np.array([p0, p1]) + off * left))
    turn_i = 0
    i = 0
    while i < len(t) - 40:
        if moving[i] and abs(hdg[i + 40] - hdg[i]) > math.radians(45):
            # the corner's side road: straight on from where the turn starts (the first
            # sample off the straight), not from 20 s before it, where it would lie on the
            # approach to the corner, on the route itself
            j = i + int(np.argmax(~straight[i:i + 41]))
            a = xy[j]
            d = np.array([math.sin(hdg[i]), math.cos(hdg[i])])
            turn_i += 1
            feats.append(({"id": f"side{turn_i}", "role": "distractor"}, np.array([a, a + 150.0 * d])))
            i += 80
        else:
            i += 1
    return {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": props, "geometry": {"type": "LineString",
                                                              "coordinates": _lonlat(lat0, lon0, c)}}
        for props, c in feats]}


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 2:
        print("usage: python -m bench.roadgen SCENARIO OUT.geojson", file=sys.stderr)
        return 2
    Path(args[1]).write_text(json.dumps(network_doc(args[0]), indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
