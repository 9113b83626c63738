"""Progress on stderr for long runs (the one module using tqdm).

For a person at a terminal (stderr is a TTY) a bar redrawn in place; for a log (stderr a
file or a pipe) plain lines, one when the work starts and one each time it passes another
tenth, each ending with a newline -- never a carriage-return frame. What a log holds is
therefore bounded (at most 11 lines per bar) and reads the same in any viewer.

An interrupt (Ctrl-C, SIGTERM) leaves a bar where it stood: the line is ended (after the
terminal's ``^C``) without drawing the bar again, so what the bench says next starts on a
line of its own; :func:`end_line` does the same for every bar still drawn (the message of
an interrupt caught elsewhere, the note of a second signal).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from typing import TextIO

from tqdm import tqdm

__all__ = ["progress_bar", "end_line", "is_terminal"]

#: Bars drawn on a terminal and not yet closed (their line is open: no newline after them).
_OPEN: list[tqdm] = []


def is_terminal(stream: TextIO | None = None) -> bool:
    """Whether ``stream`` (stderr by default) is a terminal (a closed or odd stream is not)."""
    stream = sys.stderr if stream is None else stream
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


def end_line() -> None:
    """End the line of every bar still drawn, without drawing it again (before a message
    printed while a bar is open, such as an interrupt's)."""
    while _OPEN:
        _cut(_OPEN[-1])


def _cut(bar: tqdm) -> None:
    if bar not in _OPEN:  # closed, or its line ended already
        return
    _OPEN.remove(bar)
    with suppress(OSError, ValueError):  # a closed or broken stderr: nothing to end
        bar.fp.write("\n")
        bar.fp.flush()
    bar.leave = False  # closing now clears only the fresh line below the bar, never redraws it
    with suppress(OSError, ValueError):
        bar.close()


@contextmanager
def progress_bar(
    label: str, total: float, unit: str = "s", enabled: bool = True, stream: TextIO | None = None
) -> Iterator[Callable[[float, float], None]]:
    """A callback ``(done, total)`` showing progress on ``stream`` (stderr by default): a bar
    on a terminal, plain lines otherwise (module docstring); silent when disabled."""
    if not enabled:
        yield lambda done, tot: None
        return
    stream = sys.stderr if stream is None else stream
    if not is_terminal(stream):
        with _lines(label, total, unit, stream) as update:
            yield update
        return
    bar = tqdm(
        total=round(total, 3),
        desc=label,
        unit=unit,
        file=stream,
        dynamic_ncols=True,
        leave=True,
        bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.0f}/{total:.0f} {unit} [{elapsed}<{remaining}]",
    )
    _OPEN.append(bar)

    def update(done: float, tot: float) -> None:
        if bar.disable:
            return
        if round(tot, 3) != bar.total:  # a total known only once the work is planned
            bar.total = round(tot, 3)
        bar.update(round(min(done, tot), 3) - bar.n)

    try:
        yield update
    except BaseException:  # an interrupt or a failure: end the line where the bar stood
        _cut(bar)
        raise
    finally:
        if bar in _OPEN:
            _OPEN.remove(bar)
        bar.close()


@contextmanager
def _lines(label: str, total: float, unit: str, stream: TextIO) -> Iterator[Callable[[float, float], None]]:
    """Plain progress lines: the start, each tenth passed, and the end when it was reached."""
    state = {"tenth": -1, "done": 0.0, "total": float(total), "shown": -1.0}

    def say(done: float, tot: float) -> None:
        pct = 100.0 if tot <= 0 else min(100.0, 100.0 * done / tot)
        shown = f"{math.floor(done + 1e-9)}/{tot:.0f} {unit} ({math.floor(pct + 1e-9)}%)"
        print(f"{label}: {shown}", file=stream, flush=True)
        state["shown"] = done

    def update(done: float, tot: float) -> None:
        done = min(done, tot)
        state["done"], state["total"] = done, tot
        tenth = 10 if tot <= 0 else math.floor(10 * done / tot + 1e-9)
        if tenth > state["tenth"]:
            state["tenth"] = tenth
            say(done, tot)

    yield update
    # a normal end: the last figure, unless it was just shown (an exception shows nothing more)
    if state["tenth"] >= 0 and state["shown"] != state["done"]:
        say(state["done"], state["total"])
