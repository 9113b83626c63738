"""Progress bars for long runs (the one module using tqdm)."""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from tqdm import tqdm

__all__ = ["progress_bar"]


@contextmanager
def progress_bar(
    label: str, total: float, unit: str = "s", enabled: bool = True
) -> Iterator[Callable[[float, float], None]]:
    """A callback ``(done, total)`` drawing a bar on stderr; silent when disabled."""
    if not enabled:
        yield lambda done, tot: None
        return
    bar = tqdm(
        total=round(total, 3),
        desc=label,
        unit=unit,
        file=sys.stderr,
        dynamic_ncols=True,
        leave=True,
        bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.0f}/{total:.0f} {unit} [{elapsed}<{remaining}]",
    )

    def update(done: float, tot: float) -> None:
        if round(tot, 3) != bar.total:  # a total known only once the work is planned
            bar.total = round(tot, 3)
        bar.update(round(min(done, tot), 3) - bar.n)

    try:
        yield update
    finally:
        bar.close()
