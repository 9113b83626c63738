"""The matcher's plain-float paths give exactly what the numpy formulation gave: candidates
(RoadNetwork.project vectorized), route distances (the node distance arrays read on every
call) and the Viterbi's argmax (np.argmax). Bit for bit, on the shipped S001 network."""

import math
import struct
from pathlib import Path

import numpy as np
import pytest
import shapely

from bench.estimators.mapmatch import RoadNetwork, _argmax
from bench.scoring.roadmap import Candidate

NET = Path(__file__).parents[2] / "test_cases" / "scenarios" / "S001_roads.geojson"


def _bits(x) -> bytes:
    return struct.pack("<d", float(x))


def _key(c: Candidate) -> tuple:
    return (c.segment, *(_bits(v) for v in (c.east, c.north, c.distance, c.along, c.heading)))


def _reference_candidates(net: RoadNetwork, east: float, north: float, radius: float) -> list[Candidate]:
    """The numpy formulation: project() over the segments the tree returns, argsort."""
    idx = np.asarray(net._tree.query(shapely.points(east, north), predicate="dwithin", distance=radius), dtype=int)
    if idx.size == 0:
        return []
    dist, along = net.project(idx, np.full(idx.size, east), np.full(idx.size, north))
    order = np.argsort(dist)
    seg, dist, along = idx[order], dist[order], along[order]
    f = along / net.length[seg]
    p = net.a[seg] + f[:, None] * (net.b[seg] - net.a[seg])
    return [Candidate(i, pe, pn, d, s, h) for i, (pe, pn), d, s, h in
            zip(seg.tolist(), p.tolist(), dist.tolist(), along.tolist(), net.heading[seg].tolist(), strict=True)]


def _reference_route(net: RoadNetwork, cache: dict, c1: Candidate, c2: Candidate, limit: float) -> float:
    """Node distance arrays (cached per node as the network caches them) read on every call."""
    from scipy.sparse.csgraph import dijkstra

    if c1.segment == c2.segment:
        return abs(c2.along - c1.along)
    i, j = c1.segment, c2.segment
    best = math.inf
    for n1, d1 in ((net.node_a[i], c1.along), (net.node_b[i], net.length[i] - c1.along)):
        got = cache.get(int(n1))
        if got is None or got[1] < limit:
            got = cache[int(n1)] = (dijkstra(net._graph, directed=False, indices=int(n1), limit=max(limit, 500.0)),
                                    max(limit, 500.0))
        for n2, d2 in ((net.node_a[j], c2.along), (net.node_b[j], net.length[j] - c2.along)):
            best = min(best, d1 + got[0][n2] + d2)
    return best


@pytest.fixture(scope="module")
def net():
    return RoadNetwork.from_geojson(NET)


def _points(net: RoadNetwork, rng: np.random.Generator) -> list[tuple[float, float]]:
    """Random points near the roads, the vertices themselves (ties between the segments
    meeting there) and points at the edge of the search radius."""
    pts = [(float(e), float(n)) for e, n in np.concatenate([net.a, net.b])]
    s = rng.uniform(0, 1, 400)
    k = rng.integers(0, len(net.a), 400)
    base = net.a[k] + s[:, None] * (net.b[k] - net.a[k])
    pts += [(float(e), float(n)) for e, n in base + rng.normal(0, 12, (400, 2))]
    pts += [(float(e), float(n)) for e, n in net.a[k[:50]] + np.array([30.0, 0.0])]
    return pts


def test_candidates_are_the_numpy_formulation_bit_for_bit(net):
    rng = np.random.default_rng(5)
    for e, n in _points(net, rng):
        for radius in (30.0, 8.0):
            got, ref = net.candidates(e, n, radius), _reference_candidates(net, e, n, radius)
            assert [_key(c) for c in got] == [_key(c) for c in ref]


def test_route_distances_are_those_read_from_the_node_arrays(net):
    """A fresh network and the reference see the same limits in the same order: growing
    ones (arrays recomputed, the pair cache dropped) and smaller ones after them (an array
    of a larger limit reused, as before); every pair of segments, a random point on each."""
    fresh = RoadNetwork.from_geojson(NET)
    cache: dict = {}
    rng = np.random.default_rng(6)
    pts = [Candidate(i, 0.0, 0.0, 0.0, float(rng.uniform(0, net.length[i])), 0.0) for i in range(len(net.a))]
    pts += [Candidate(i, 0.0, 0.0, 0.0, float(s), 0.0) for i in range(3) for s in (0.0, net.length[i])]
    pairs = [(c1, c2) for c1 in pts for c2 in pts]
    seen = set()
    for limit in (80.0, 80.0, 650.0, 90.0, 2000.0, 80.0, 20000.0, 100.0):
        for k in np.flatnonzero(rng.uniform(size=len(pairs)) < 0.5):  # some pairs, in an order
            c1, c2 = pairs[k]
            r = fresh.route_distance(c1, c2, limit)
            assert _bits(r) == _bits(_reference_route(fresh, cache, c1, c2, limit))
            seen.add((limit, math.isfinite(r) and r > 2000.0))
    assert (80.0, True) in seen  # distances only an array of a larger limit holds were read


def test_argmax_is_numpys():
    rng = np.random.default_rng(7)
    pool = [0.0, -0.0, 1.0, -1.0, math.inf, -math.inf, math.nan, 2.5]
    for n in range(1, 9):
        for _ in range(300):
            v = [pool[i] for i in rng.integers(len(pool), size=n)]
            assert _argmax(v) == int(np.argmax(np.array(v)))
