"""Road networks: GeoJSON LineStrings projected to a local ENU plane (metres).

A network file is a GeoJSON FeatureCollection of LineString features, coordinates
``[lon, lat]`` in degrees (WGS-84), properties ``id`` (required), ``role`` ("route" for the
scenario's own road, "distractor" otherwise; default "distractor") and optional
``max_speed`` (m/s). Geometry uses shapely (this module is its one user); the topology joins
line endpoints and shared vertices (within 1 cm) into a graph for route distances.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import shapely
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from bench.config.files import TEXT_LIMIT, parse_json, read_bytes
from bench.errors import ConfigError

R_EARTH = 6_378_137.0
__all__ = ["Candidate", "RoadNetwork", "R_EARTH"]


@dataclass(frozen=True)
class Candidate:
    """A point on a road segment near an observed position."""

    segment: int  # index into the network's segments
    east: float
    north: float
    distance: float  # m, from the observed position
    along: float  # m, from the segment's start
    heading: float  # rad, segment direction clockwise from north


class RoadNetwork:
    """Road segments in a local ENU plane around ``origin`` (lat, lon in rad)."""

    def __init__(self, lines: list[tuple[str, str, float | None, np.ndarray]], origin: tuple[float, float]):
        self.origin = origin
        self.lat0, self.lon0 = origin
        a, b, fid, role, vmax = [], [], [], [], []
        for ident, rl, speed, lonlat in lines:
            en = self.to_enu(np.radians(lonlat[:, 1]), np.radians(lonlat[:, 0]))
            for i in range(len(en) - 1):
                if np.hypot(*(en[i + 1] - en[i])) > 0:
                    a.append(en[i])
                    b.append(en[i + 1])
                    fid.append(ident)
                    role.append(rl)
                    vmax.append(math.inf if speed is None else speed)
        self.a = np.array(a).reshape(-1, 2)
        self.b = np.array(b).reshape(-1, 2)
        self.feature_id = fid
        self.role = role
        self.max_speed = np.array(vmax)
        d = self.b - self.a
        self.length = np.hypot(d[:, 0], d[:, 1])
        self.heading = np.arctan2(d[:, 0], d[:, 1])
        self.is_route = np.array([r == "route" for r in role])
        self._geoms = shapely.linestrings(np.stack([self.a, self.b], axis=1))
        self._tree = shapely.STRtree(self._geoms)
        # per segment as plain floats (start east, north; b - a; length; length squared;
        # heading): the matcher's few candidates are computed without numpy's per-call cost
        self._seg = [(ax, ay, dx, dy, ln, ln * ln, h) for (ax, ay), (dx, dy), ln, h in
                     zip(self.a.tolist(), d.tolist(), self.length.tolist(), self.heading.tolist(), strict=True)]
        self._radius = np.array([math.nan])  # the last search radius, as the tree query takes it
        self._build_graph()

    # ---- loading ---------------------------------------------------------------------------
    @classmethod
    def from_geojson(cls, path: str | Path, origin: tuple[float, float] | None = None) -> RoadNetwork:
        """Load a network file; ``origin`` (lat, lon, rad) defaults to the first vertex."""
        text = read_bytes(path, what="road network file", limit=TEXT_LIMIT)  # a regular file of bounded size
        return cls.from_geojson_text(text, file=str(path), origin=origin)

    @classmethod
    def from_geojson_text(cls, text: str | bytes, *, file: str, origin: tuple[float, float] | None = None
                          ) -> RoadNetwork:
        """A network from the text of a GeoJSON file (``file`` names it in errors)."""
        p = file
        try:  # nested at most 64 levels, every number finite
            doc = parse_json(text, file=p, what="road network file")
        except ConfigError as exc:
            raise ConfigError(f"malformed GeoJSON: {exc.reason}", file=p, key=exc.key) from None
        if not isinstance(doc, dict) or doc.get("type") != "FeatureCollection":
            raise ConfigError("expected a GeoJSON FeatureCollection", file=p, key="type")
        lines = []
        for k, feat in enumerate(doc.get("features") or []):
            key = f"features[{k}]"
            geom = feat.get("geometry") if isinstance(feat, dict) else None
            props = (feat.get("properties") or {}) if isinstance(feat, dict) else {}
            if not isinstance(geom, dict) or geom.get("type") != "LineString":
                raise ConfigError("expected a LineString geometry", file=p, key=f"{key}.geometry")
            if "id" not in props:
                raise ConfigError("expected a property 'id'", file=p, key=f"{key}.properties.id")
            role = props.get("role", "distractor")
            if role not in ("route", "distractor"):
                raise ConfigError(f"expected role 'route' or 'distractor', found {role!r}", file=p,
                                  key=f"{key}.properties.role")
            speed = props.get("max_speed")
            if speed is not None and not (isinstance(speed, int | float) and math.isfinite(speed) and speed > 0):
                raise ConfigError(f"expected a positive max_speed in m/s, found {speed!r}", file=p,
                                  key=f"{key}.properties.max_speed")
            try:
                xy = np.array(geom.get("coordinates"), dtype=float)
            except (TypeError, ValueError):
                xy = np.empty((0,))
            if xy.ndim != 2 or xy.shape[1] not in (2, 3) or len(xy) < 2:
                raise ConfigError("expected at least 2 [lon, lat] points", file=p, key=f"{key}.geometry.coordinates")
            if not np.all(np.isfinite(xy)) or np.any(np.abs(xy[:, 0]) > 180) or np.any(np.abs(xy[:, 1]) > 90):
                raise ConfigError("coordinates out of range (lon within ±180, lat within ±90 deg)", file=p,
                                  key=f"{key}.geometry.coordinates")
            lines.append((str(props["id"]), role, speed, xy[:, :2]))
        if not lines:
            raise ConfigError("expected at least one LineString feature", file=p, key="features")
        if origin is None:
            origin = (math.radians(lines[0][3][0, 1]), math.radians(lines[0][3][0, 0]))
        return cls(lines, origin)

    # ---- projection ------------------------------------------------------------------------
    def to_enu(self, lat: np.ndarray | float, lon: np.ndarray | float) -> np.ndarray:
        """(N, 2) east, north in m (equirectangular about the origin; ample for a city)."""
        lat, lon = np.asarray(lat, float), np.asarray(lon, float)
        e = (lon - self.lon0) * R_EARTH * math.cos(self.lat0)
        n = (lat - self.lat0) * R_EARTH
        return np.stack([e, n], axis=-1)

    def to_enu_point(self, lat: float, lon: float) -> tuple[float, float]:
        """:meth:`to_enu` of one point, as floats (the same arithmetic, without arrays)."""
        return float((lon - self.lon0) * R_EARTH * math.cos(self.lat0)), float((lat - self.lat0) * R_EARTH)

    def to_latlon(self, east: float, north: float) -> tuple[float, float]:
        """Inverse of :meth:`to_enu` (rad)."""
        return self.lat0 + north / R_EARTH, self.lon0 + east / (R_EARTH * math.cos(self.lat0))

    # ---- geometry --------------------------------------------------------------------------
    def project(self, seg: np.ndarray, east: np.ndarray, north: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance of points to segments ``seg`` (elementwise) and their along-track position."""
        a, d = self.a[seg], self.b[seg] - self.a[seg]
        px, py = east - a[..., 0], north - a[..., 1]
        s = np.clip((px * d[..., 0] + py * d[..., 1]) / self.length[seg] ** 2, 0.0, 1.0)
        return np.hypot(px - s * d[..., 0], py - s * d[..., 1]), s * self.length[seg]

    def candidates(self, east: float, north: float, radius: float) -> list[Candidate]:
        """Segments within ``radius`` m of a point, nearest first."""
        # a one-point array (the same query, without the scalar's broadcasting)
        if self._radius[0] != radius:
            self._radius = np.array([radius], dtype=float)
        segs = self._tree.query(shapely.points(np.array([[east, north]])), predicate="dwithin",
                                distance=self._radius)[1].tolist()
        if not segs:
            return []
        # :meth:`project` element by element on plain floats (the same operations in the same
        # order; np.clip's semantics, -0.0 and nan kept), np.hypot and np.argsort as there
        qx, qy, along = [], [], []
        seg_data = self._seg
        for i in segs:
            ax, ay, dx, dy, ln, l2, _ = seg_data[i]
            px, py = east - ax, north - ay
            s = (px * dx + py * dy) / l2
            s = 0.0 if s < 0.0 else (1.0 if s > 1.0 else s)
            qx.append(px - s * dx)
            qy.append(py - s * dy)
            along.append(s * ln)
        dist = np.hypot(qx, qy)
        order = dist.argsort().tolist()  # (np.argsort's own call)
        dl = dist.tolist()
        out = []
        for k in order:
            i = segs[k]
            ax, ay, dx, dy, ln, _, h = seg_data[i]
            s = along[k]
            f = s / ln  # the point on the segment: a + (along / length) (b - a)
            out.append(Candidate(i, ax + f * dx, ay + f * dy, dl[k], s, h))
        return out

    def nearest(
        self, east: np.ndarray, north: np.ndarray, mask: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Per point, index of and distance to the nearest segment (among ``mask`` if given)."""
        segs = np.arange(len(self.a)) if mask is None else np.flatnonzero(mask)
        e, n = np.asarray(east, float)[:, None], np.asarray(north, float)[:, None]
        best_i = np.empty(e.shape[0], dtype=int)
        best_d = np.empty(e.shape[0])
        for lo in range(0, e.shape[0], 512):  # chunks bound the memory
            d, _ = self.project(segs[None, :], e[lo:lo + 512], n[lo:lo + 512])
            k = np.argmin(d, axis=1)
            best_i[lo:lo + 512] = segs[k]
            best_d[lo:lo + 512] = d[np.arange(len(k)), k]
        return best_i, best_d

    # ---- topology --------------------------------------------------------------------------
    def _build_graph(self) -> None:
        pts = np.concatenate([self.a, self.b])
        keys = np.round(pts / 0.01).astype(np.int64)
        _, node = np.unique(keys, axis=0, return_inverse=True)
        node = node.ravel()
        m = len(self.a)
        self.node_a, self.node_b = node[:m], node[m:]
        n = int(node.max()) + 1
        w = np.concatenate([self.length, self.length])
        self._graph = csr_matrix((w, (np.concatenate([self.node_a, self.node_b]),
                                      np.concatenate([self.node_b, self.node_a]))), shape=(n, n))
        self._dist_cache: dict[int, tuple[np.ndarray, float]] = {}
        #: (segment i, segment j) -> (limit, the node-to-node distances a-a, a-b, b-a, b-b) as
        #: read from the arrays of _dist_cache (limit: the smaller of the two arrays' limits);
        #: cleared whenever _dist_cache changes, so an entry is what those arrays hold now
        self._pair_cache: dict[tuple[int, int], tuple[float, float, float, float, float]] = {}
        self._nodes = list(zip(self.node_a.tolist(), self.node_b.tolist(), strict=True))

    def _from_node(self, node: int, limit: float) -> np.ndarray:
        got = self._dist_cache.get(node)
        if got is None or got[1] < limit:
            d = dijkstra(self._graph, directed=False, indices=node, limit=max(limit, 500.0))
            got = (d, max(limit, 500.0))
            if len(self._dist_cache) > 4096:
                self._dist_cache.clear()
            self._dist_cache[node] = got
            self._pair_cache.clear()
        return got[0]

    def _pair(self, i: int, j: int, limit: float) -> tuple[float, float, float, float]:
        """The node-to-node distances a-a, a-b, b-a, b-b from segment ``i`` to segment ``j``,
        read as route_distance always read them; kept in ``_pair_cache`` while both arrays
        they were read from stay cached."""
        (a1, b1), (a2, b2) = self._nodes[i], self._nodes[j]
        da = self._from_node(a1, limit)
        daa, dab = float(da[a2]), float(da[b2])
        db = self._from_node(b1, limit)
        dba, dbb = float(db[a2]), float(db[b2])
        ga, gb = self._dist_cache.get(a1), self._dist_cache.get(b1)
        if ga is not None and gb is not None and ga[0] is da and gb[0] is db:
            self._pair_cache[(i, j)] = (min(ga[1], gb[1]), daa, dab, dba, dbb)
        return daa, dab, dba, dbb

    def route_distance(self, c1: Candidate, c2: Candidate, limit: float = 500.0) -> float:
        """Shortest distance along the network between two candidate points (inf beyond ``limit``)."""
        i, j = c1.segment, c2.segment
        if i == j:
            return abs(c2.along - c1.along)
        got = self._pair_cache.get((i, j))
        if got is None or got[0] < limit:  # _from_node would (re)compute an array: through it
            daa, dab, dba, dbb = self._pair(i, j, limit)
        else:
            _, daa, dab, dba, dbb = got
        u1, u2 = c1.along, c2.along
        v1, v2 = self._seg[i][4] - u1, self._seg[j][4] - u2
        # the four ways in, in their order: start node of i to start node of j, ... end to end
        best = min(math.inf, u1 + daa + u2)
        best = min(best, u1 + dab + v2)
        best = min(best, v1 + dba + u2)
        return min(best, v1 + dbb + v2)
