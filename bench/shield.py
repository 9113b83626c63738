"""Sections a signal must not cut: a KeyboardInterrupt from SIGINT or SIGTERM
(:func:`bench.cli.app.interrupts`) that arrives inside one is held until its end.

A Python signal handler runs between two bytecodes of the main thread, wherever it is.
Raised in the middle of a recording write (the MCAP library has taken the open chunk's
messages and is compressing them) the interrupt would drop that whole chunk from a file
that is then finished as if nothing were missing; raised between receiving the DUT's
frames and recording them, it would drop them. Code that must finish what it started
runs inside :func:`shielded`; the signal handler asks :func:`hold` whether to keep the
interrupt for later. A third signal (the user insists) is never held.

Only the main thread handles signals, so the state is a plain counter.
"""

from __future__ import annotations

__all__ = ["shielded", "hold", "depth"]

_depth = 0
_held: str | None = None


def depth() -> int:
    """How many shielded sections are open (0: a signal may raise at once)."""
    return _depth


def hold(name: str) -> bool:
    """Called by the signal handler: True if an interrupt named ``name`` is kept until the
    open shielded section ends (then it is raised there), False if there is none open."""
    global _held
    if _depth == 0:
        return False
    if _held is None:
        _held = name
    return True


class _Shielded:
    """The context manager of :func:`shielded` (a class: it wraps every recording write)."""

    __slots__ = ()

    def __enter__(self) -> None:
        global _depth
        _depth += 1

    def __exit__(self, *exc: object) -> None:
        global _depth, _held
        _depth -= 1
        if _depth == 0 and _held is not None:
            name, _held = _held, None
            raise KeyboardInterrupt(name)


_SHIELDED = _Shielded()


def shielded() -> _Shielded:
    """A section that an interrupt does not cut: one that arrives inside it is raised as
    :class:`KeyboardInterrupt` when the outermost section ends."""
    return _SHIELDED
