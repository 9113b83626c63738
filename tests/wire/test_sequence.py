"""Sequence checks: counters with wrap-around, losses, repeats, duplicates, across batches."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.wire.sequence import SEQ_KINDS, CounterSequence, SequenceChecker


@settings(max_examples=200, deadline=None)
@given(
    st.sampled_from([16, 256]),
    st.integers(0, 255),
    st.lists(st.integers(0, 14), min_size=1, max_size=300),
    st.integers(1, 50),
)
def test_lost_frames_are_counted_through_wrap_around(modulus, start, gaps, batch):
    """Frames sent with counters +1 mod m, some lost (fewer than m - 1 in a row): every loss counted."""
    sent = CounterSequence(modulus, start)
    counters, rows = [], []
    for k, gap in enumerate(gaps):
        sent.take(gap)  # lost on the way
        c = int(sent.take(1)[0])
        counters.append(c)
        rows.append([c, k % 256, k // 256])
    checker = SequenceChecker(modulus, np.array([0, 0xFF, 0xFF], np.uint8))
    labels, lost = [], []
    for a in range(0, len(counters), batch):  # however the stream is cut
        lab, lo = checker.check(np.array(counters[a : a + batch]), np.array(rows[a : a + batch], np.uint8))
        labels += lab.tolist()
        lost += lo.tolist()
    want = [0] + [SEQ_KINDS.index("skip") if g else 0 for g in gaps[1:]]
    assert labels == want
    assert lost == [0, *gaps[1:]]


def test_repeat_duplicate_and_stale():
    checker = SequenceChecker(16, np.array([0, 0xFF], np.uint8))
    rows = np.array([[14, 1], [15, 2], [15, 2], [15, 3], [0, 3], [1, 4]], np.uint8)
    labels, lost = checker.check(rows[:, 0], rows)
    assert [SEQ_KINDS[i] for i in labels] == ["ok", "ok", "duplicate", "repeat", "stale", "ok"]
    assert lost.tolist() == [0] * 6
    assert CounterSequence(16, 14).take(4).tolist() == [14, 15, 0, 1]
