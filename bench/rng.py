"""Named, independent random streams derived from one run seed.

Every noise process of a run draws from its own :class:`numpy.random.Generator`, keyed by
a stable name (``stream(seed, "imu", "gyro", "arw")``). Adding a sensor or a process does
not change the noise of the others, and a process draws the same numbers however its
samples are split into chunks.
"""

from __future__ import annotations

import hashlib

import numpy as np

__all__ = ["stream", "spawn_key"]


def spawn_key(*names: str) -> list[int]:
    """Stable 32-bit words for a tuple of names (independent of ``PYTHONHASHSEED``)."""
    digest = hashlib.sha256("/".join(names).encode()).digest()
    return [int.from_bytes(digest[i : i + 4], "little") for i in range(0, 16, 4)]


def stream(seed: int, *names: str) -> np.random.Generator:
    """The generator of the stream ``names`` of run ``seed``."""
    if seed < 0:
        raise ValueError(f"seed must be a non-negative integer, found {seed}")
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([seed, *spawn_key(*names)])))
