"""Compile a numba kernel ahead of its first call (an estimator's ``warm_up``).

A kernel compiled lazily compiles at its first call, inside a step: through the harness
that is seconds to a minute (a cold cache on a loaded machine) without an answer to the
bench's BENCH_TIME. :func:`compile_for` compiles (or loads from numba's cache) the
specialization for the numba types of example arguments, without running the kernel, so
an estimator's ``warm_up`` can build arguments typed as its step builds them (the same
dtypes and memory layouts: an IMU field view is non-contiguous) and compile before the
run. A later call with arguments of those types, or of types numba converts to them
safely, reuses that compilation.
"""

from __future__ import annotations

from typing import Any

from numba import typeof

__all__ = ["compile_for"]


def compile_for(kernel: Any, *args: Any) -> None:
    """Compile the numba dispatcher ``kernel`` for the types of ``args`` (not called)."""
    kernel.compile(tuple(typeof(a) for a in args))
