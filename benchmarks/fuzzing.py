"""The counting and the byte mutations of the fuzz campaigns (benchmarks/bench_fuzz.py)."""

from __future__ import annotations

import itertools
import time
import traceback
from collections import Counter
from pathlib import Path

import numpy as np

EPOCH_UTC = 1_748_736_000 * 10**9
HOSTILE = [
    b"nan", b"inf", b"-inf", b"1e400", b"1e308", b"999999", b"9999", b"-1", b"290223", b"310299", b"000000",
    b"1_0", b"+5", b" 5", b"0x1F", b"", b"99999999999999999999", b"12.5.3", b"-0", b"256", b"13", b"9000.0",
]  # fmt: skip


class Campaign:
    """Counts of one campaign."""

    def __init__(self, name: str, total: int):
        self.name, self.total = name, total
        self.inputs = self.decoded = self.mismatches = 0
        self.crashes: Counter[str] = Counter()
        self.one_frame: Counter[str] = Counter()
        self.t0 = time.perf_counter()
        self._next = max(1, total // 10)

    def crash(self, exc: BaseException) -> None:
        tb = traceback.extract_tb(exc.__traceback__)[-1]
        self.crashes[f"{type(exc).__name__}: {str(exc)[:60]} ({Path(tb.filename).name}:{tb.lineno})"] += 1

    def progress(self) -> None:
        if self.inputs >= self._next:
            self._next += max(1, self.total // 10)
            print(
                f"  {self.name}: {self.inputs:>9,} inputs, {sum(self.crashes.values())} crashes, "
                f"{self.mismatches} split mismatches, {time.perf_counter() - self.t0:6.1f} s",
                flush=True,
            )

    def report(self, rejected: dict[str, int], decoded_what: str) -> None:
        dt = time.perf_counter() - self.t0
        print(f"\n{self.name}")
        print(f"  inputs            {self.inputs:,}")
        print(f"  decoded           {self.decoded:,} {decoded_what}")
        print(f"  rejected by kind  {dict(sorted(rejected.items()))}")
        print(f"  one-frame decoder {dict(sorted(self.one_frame.items()))}")
        print(f"  crashes           {sum(self.crashes.values())}")
        for sig, n in self.crashes.most_common(10):
            print(f"    {n:>8}  {sig}")
        print(f"  split mismatches  {self.mismatches}")
        print(f"  elapsed           {dt:.1f} s ({self.inputs / dt:,.0f} inputs/s)", flush=True)

    @property
    def failed(self) -> bool:
        return bool(self.crashes) or self.mismatches > 0


# ---------------------------------------------------------------------------- byte mutations
def mutate(rng: np.random.Generator, data: bytes, specials: bytes) -> bytes:
    """0..3 random edits: bit flips, a cut, inserted bytes (biased to ``specials``), a deleted
    range, a repeated range."""
    d = bytearray(data)
    for _ in range(int(rng.integers(0, 4))):
        op = int(rng.integers(5))
        n = len(d)
        if op == 0 and n:
            for i in rng.integers(0, n, int(rng.integers(1, 4))).tolist():
                d[i] ^= 1 << int(rng.integers(8))
        elif op == 1 and n:
            d = d[: int(rng.integers(0, n))] if rng.random() < 0.5 else d[int(rng.integers(0, n)) :]
        elif op == 2:
            ins = rng.integers(0, 256, int(rng.integers(1, 24)), dtype=np.uint8)
            sp = np.frombuffer(specials, np.uint8)
            mask = rng.random(ins.size) < 0.5
            ins[mask] = sp[rng.integers(0, sp.size, int(mask.sum()))]
            i = int(rng.integers(0, n + 1))
            d[i:i] = ins.tobytes()
        elif op == 3 and n:
            i = int(rng.integers(0, n))
            del d[i : i + int(rng.integers(1, 50))]
        elif n:
            i = int(rng.integers(0, n))
            j = min(n, i + int(rng.integers(1, 60)))
            d[j:j] = d[i:j]
    return bytes(d)


def noise(rng: np.random.Generator, specials: bytes, hi: int = 120) -> bytes:
    b = rng.integers(0, 256, int(rng.integers(0, hi)), dtype=np.uint8)
    sp = np.frombuffer(specials, np.uint8)
    mask = rng.random(b.size) < 0.3
    b[mask] = sp[rng.integers(0, sp.size, int(mask.sum()))]
    return b.tobytes()


def pieces(rng: np.random.Generator, data: bytes) -> list[bytes]:
    """``data`` cut at random points (byte by byte for one input in ten)."""
    if rng.random() < 0.1:
        return [data[i : i + 1] for i in range(len(data))]
    k = int(rng.integers(0, 5))
    cuts = np.unique(rng.integers(0, len(data) + 1, k)) if data else np.zeros(0, np.int64)
    edges = [0, *cuts.tolist(), len(data)]
    return [data[a:b] for a, b in itertools.pairwise(edges)]
