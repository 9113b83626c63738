"""How a run ended: the result of :func:`bench.run.engine.run` and the mapping from the
exception that stopped a run to its ``run_end`` status and reason."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from bench.clock.pacing import TimingSummary
from bench.errors import BenchError, DutError, LinkError

__all__ = ["RunResult", "TimingBudgetError", "status_of", "reason_of"]


class TimingBudgetError(BenchError):
    """A real-time run was later than its budget allows."""


@dataclass
class RunResult:
    """How a run ended and what it produced."""

    path: Path
    status: str
    reason: str = ""
    elapsed_s: float = 0.0
    bench_s: float = 0.0
    counts: dict[str, int] = field(default_factory=dict)
    timing: TimingSummary | None = None
    dut_exit: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """True when the run went to its end."""
        return self.status == "complete"


def status_of(exc: BaseException) -> str:
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted"
    if isinstance(exc, DutError):
        return "dut_failed" if exc.certain else "dut_error"
    if isinstance(exc, LinkError):
        return "link_lost"
    if isinstance(exc, TimingBudgetError):
        return "timing_budget"
    return "error"


def reason_of(exc: BaseException) -> str:
    if isinstance(exc, KeyboardInterrupt):
        return f"interrupted by {exc.args[0]}" if exc.args else "interrupted (KeyboardInterrupt)"
    return str(exc) if isinstance(exc, BenchError) else f"{type(exc).__name__}: {exc}"
