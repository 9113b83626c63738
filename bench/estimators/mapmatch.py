"""HMM map matching (seed 001 section 6), solved by an online Viterbi with a fixed lag.

Hidden state: the road segment (a candidate point on it) at each epoch. Observation model
(eq. 23): log N(distance to the segment; sigma_distance) plus log N(heading difference;
sigma_heading * speed_ref / max(speed, speed_ref)) - the heading term is flat below
``min_speed`` (standstill). Transition model (eq. 24): log of (1/beta) exp(-d/beta), d =
|straight-line distance between the two positions - route distance between the
candidates along the network|; the speed factor V of eq. 24 is kept as a penalty when the
route speed exceeds a road's ``max_speed`` by more than 50 %. All in log-probabilities.

Interface (used by the seed001 estimator)::

    net = RoadNetwork.from_geojson(path, origin=None)
    mm = OnlineMatcher(net, sigma_distance=5.0, sigma_heading=0.35, beta=3.0, radius=30.0, lag=2)
    m = mm.update(t_ns, lat, lon, heading, speed)   # rad, rad, rad (clockwise from north), m/s
    # m is None until the first decision, else Match(t_ns, lat, lon, segment, feature_id,
    # role, distance, matched): the decision for the epoch ``lag`` updates back.

An epoch with no candidate within ``radius`` comes back unmatched (``matched`` False, its own
position) and restarts the chain; so does a gap longer than ``max_gap`` seconds.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from bench.scoring.roadmap import Candidate, RoadNetwork

__all__ = ["Match", "OnlineMatcher", "RoadNetwork", "match"]


@dataclass(frozen=True)
class Match:
    """The matched position of one epoch (lat, lon in rad)."""

    t_ns: int
    lat: float
    lon: float
    segment: int  # -1 when unmatched
    feature_id: str | None
    role: str | None
    distance: float  # m, from the input position to the matched point (0 when unmatched)
    matched: bool


@dataclass
class _Epoch:
    t_ns: int
    east: float
    north: float
    lat: float
    lon: float
    cands: list[Candidate]
    score: list[float]  # best log-probability per candidate
    back: list[int]  # predecessor index per candidate (-1: chain start)


def _argmax(v: list[float]) -> int:
    """``np.argmax`` of a list: the first nan, else the first of the largest."""
    k, best = 0, v[0]
    if best != best:
        return 0
    for i in range(1, len(v)):
        x = v[i]
        if not x <= best:  # larger, or nan
            k, best = i, x
            if x != x:
                break
    return k


class OnlineMatcher:
    """Fixed-lag online Viterbi over candidate road segments."""

    def __init__(self, network: RoadNetwork, sigma_distance: float = 5.0, sigma_heading: float = 0.35,
                 beta: float = 3.0, radius: float = 30.0, lag: int = 2, min_speed: float = 1.0,
                 speed_ref: float = 5.0, max_gap: float = 5.0):
        for name, v in (("sigma_distance", sigma_distance), ("sigma_heading", sigma_heading), ("beta", beta),
                        ("radius", radius), ("min_speed", min_speed), ("speed_ref", speed_ref), ("max_gap", max_gap)):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be finite and positive, got {v!r}")
        if int(lag) != lag or lag < 0:
            raise ValueError(f"lag must be a non-negative integer, got {lag!r}")
        self.net = network
        self.sd, self.sh, self.beta, self.radius = sigma_distance, sigma_heading, beta, radius
        self.lag, self.min_speed, self.speed_ref, self.max_gap = int(lag), min_speed, speed_ref, max_gap
        self._win: deque[_Epoch] = deque()
        self._pending: deque[Match] = deque()
        self._vmax = [1.5 * v for v in network.max_speed.tolist()]  # per segment: faster routes penalized

    def _obs(self, cands: list[Candidate], heading: float, speed: float) -> list[float]:
        """Observation log-probability per candidate (eq. 23): the numpy formulation's
        operations on floats (``x ** 2`` as ``x * x``, np.abs and np.minimum as abs and min),
        the heading difference wrapped by np.exp and np.angle as before."""
        sd = self.sd
        lp = [-0.5 * ((c.distance / sd) * (c.distance / sd)) for c in cands]
        if speed >= self.min_speed and math.isfinite(heading):
            sh = self.sh * self.speed_ref / max(speed, self.speed_ref)
            h = np.array([c.heading for c in cands])
            wrapped = np.angle(np.exp(1j * (heading - h))).tolist()  # to (-pi, pi]
            for j, dh in enumerate(wrapped):
                dh = abs(dh)
                dh = min(dh, math.pi - dh)  # roads are two-way
                lp[j] = lp[j] - 0.5 * ((dh / sh) * (dh / sh))
        return lp

    def update(self, t_ns: int, lat: float, lon: float, heading: float, speed: float) -> Match | None:
        """Add one epoch; return the final decision for the epoch ``lag`` updates back (or None)."""
        e, n = self.net.to_enu_point(lat, lon)
        cands = self.net.candidates(e, n, self.radius)
        last = self._win[-1] if self._win else None
        if not cands:
            self._flush()
            self._pending.append(Match(t_ns, lat, lon, -1, None, None, 0.0, False))
            return self._pending.popleft()
        obs = self._obs(cands, heading, speed)
        if last is None or (t_ns - last.t_ns) * 1e-9 > self.max_gap:
            self._flush()
            ep = _Epoch(t_ns, e, n, lat, lon, cands, obs, [-1] * len(cands))
        else:
            straight = math.hypot(e - last.east, n - last.north)
            limit = straight + 10 * self.beta + 50.0
            dt = max((t_ns - last.t_ns) * 1e-9, 1e-3)
            route, beta = self.net.route_distance, self.beta
            vmax = [self._vmax[c.segment] for c in cands]
            cols: list[list[float]] = [[] for _ in cands]  # per candidate: from each of the last
            for ci, si in zip(last.cands, last.score, strict=True):
                for cj, vm, col in zip(cands, vmax, cols, strict=True):
                    r = route(ci, cj, limit)
                    if math.isfinite(r):
                        lp = -abs(straight - r) / beta
                        if r / dt > vm:
                            lp -= (r / dt - vm) / 1.0
                    else:
                        lp = -1e9
                    col.append(si + lp)
            back = [_argmax(col) for col in cols]
            score = [col[b] + o for col, b, o in zip(cols, back, obs, strict=True)]
            top = math.nan if any(x != x for x in score) else max(score)
            score = [x - top for x in score]  # keep numbers small
            ep = _Epoch(t_ns, e, n, lat, lon, cands, score, back)
        self._win.append(ep)
        if len(self._win) > self.lag:
            self._decide_oldest()
        return self._pending.popleft() if self._pending else None

    def _path(self) -> list[int]:
        k = _argmax(self._win[-1].score)
        path = [k]
        for ep in reversed(list(self._win)[1:]):
            k = ep.back[k]
            path.append(k)
        return path[::-1]

    def _emit(self, ep: _Epoch, k: int) -> None:
        c = ep.cands[k]
        lat, lon = self.net.to_latlon(c.east, c.north)
        self._pending.append(Match(ep.t_ns, lat, lon, c.segment, self.net.feature_id[c.segment],
                                   self.net.role[c.segment], c.distance, True))

    def _decide_oldest(self) -> None:
        k = self._path()[0]
        old = self._win.popleft()
        self._emit(old, k)
        if self._win:  # the decision is final: the next epoch's chain starts from it only
            nxt = self._win[0]
            nxt.score = [x if b == k else -math.inf for x, b in zip(nxt.score, nxt.back, strict=True)]
            nxt.back = [-1] * len(nxt.cands)

    def _flush(self) -> None:
        """Decide every epoch still in the window (end of a chain)."""
        if not self._win:
            return
        for ep, k in zip(list(self._win), self._path(), strict=True):
            self._emit(ep, k)
        self._win.clear()

    def finish(self) -> list[Match]:
        """Decide the epochs still in the lag window (end of data)."""
        self._flush()
        out = list(self._pending)
        self._pending.clear()
        return out


def match(matcher: OnlineMatcher, t_ns, lat, lon, heading, speed) -> list[Match]:
    """Batch helper: run ``matcher`` over arrays and return one Match per epoch, in order."""
    out: list[Match] = []
    for args in zip(t_ns, lat, lon, heading, speed, strict=True):
        m = matcher.update(int(args[0]), float(args[1]), float(args[2]), float(args[3]), float(args[4]))
        if m is not None:
            out.append(m)
    return out + matcher.finish()
