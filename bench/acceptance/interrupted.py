"""What a suite that was interrupted (Ctrl-C, SIGTERM) finished, and what it did not.

:class:`Interruption` travels from :func:`bench.acceptance.suite.run_suite` (which raises
:class:`~bench.acceptance.suite.SuiteInterrupted` carrying one) to the reports, which
mark the suite incomplete: the results record's ``interrupted`` block, the first line of
the summaries, a JUnit error, the certification report's banner.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["Interruption", "signal_name"]


@dataclass(frozen=True)
class Interruption:
    """A suite ended by an interrupt: the signal, and the case ids that finished (judged),
    did not finish (in progress) and were not run."""

    by: str
    finished: tuple[str, ...] = ()
    unfinished: tuple[str, ...] = ()
    not_run: tuple[str, ...] = ()

    def to_json(self) -> dict[str, Any]:
        """The results record's ``interrupted`` block."""
        return {"by": self.by, "finished": list(self.finished), "unfinished": list(self.unfinished),
                "not_run": list(self.not_run)}

    def cases(self) -> str:
        """``1 case(s) finished (M0); did not finish: M1; not run: M2, M3``."""
        parts = [f"{len(self.finished)} case(s) finished" + (f" ({', '.join(self.finished)})" if self.finished else "")]
        if self.unfinished:
            parts.append(f"did not finish: {', '.join(self.unfinished)}")
        if self.not_run:
            parts.append(f"not run: {', '.join(self.not_run)}")
        return "; ".join(parts)

    def headline(self) -> str:
        """One line for the top of a summary: ``INCOMPLETE: the suite was interrupted by
        SIGINT; 1 case(s) finished (M0); ...``."""
        return f"INCOMPLETE: the suite was interrupted by {self.by}; {self.cases()}"


def signal_name(exc: BaseException) -> str:
    """The signal an interrupt names (``bench`` raises ``KeyboardInterrupt("SIGTERM")``)."""
    return str(exc.args[0]) if exc.args and exc.args[0] else "KeyboardInterrupt"
