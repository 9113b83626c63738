"""The Foxglove display documents: the directly formatted encodings are the JSON encoder's bytes."""

from __future__ import annotations

import json

import numpy as np

from bench.record.foxglove import location_fix_json, location_fixes, pose_json, poses_in_frame


def _dumps(docs):
    return [json.dumps(d, separators=(",", ":")).encode() for d in docs]


def test_location_fix_and_pose_encodings_are_the_json_encoders_bytes():
    rng = np.random.default_rng(3)
    n = 500
    epoch = 1_748_736_000_000_000_000
    t = np.sort(rng.integers(0, 2_000_000_000_000, n))
    lat, lon = rng.uniform(-1.5, 1.5, n), rng.uniform(-3.1, 3.1, n)
    h = rng.normal(60.0, 300.0, n)
    lat[:3] = [0.0, -0.0, np.pi / 2]  # zeros and the pole
    h[3], h[4], h[5] = np.nan, np.inf, -np.inf  # what json.dumps writes for these too
    assert location_fix_json(epoch, t, lat, lon, h, frame_id="dut") == \
        _dumps(location_fixes(epoch, t, lat, lon, h, frame_id="dut"))
    enu = rng.normal(0.0, 1e4, (n, 3))
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    assert pose_json(epoch, t, enu, q) == _dumps(poses_in_frame(epoch, t, enu, q))
    doc = json.loads(location_fix_json(epoch, t[:1], lat[:1], lon[:1], h[:1])[0])
    assert doc["timestamp"] == {"sec": (epoch + int(t[0])) // 10**9, "nsec": (epoch + int(t[0])) % 10**9}
