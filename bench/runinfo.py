"""Facts every recording states about its run: the code that made it, the host, the
epoch (UTC of bench time zero)."""

from __future__ import annotations

import datetime as _dt
import platform
import subprocess
from typing import Any

import numpy as np

from bench import __version__
from bench.errors import ConfigError
from bench.paths import project_root

__all__ = ["DEFAULT_EPOCH", "git_commit", "parse_epoch", "host_metadata"]

#: UTC of bench time zero when a scenario does not say (``[scenario] start_utc``).
DEFAULT_EPOCH = "2025-06-01T00:00:00Z"


def git_commit() -> str:
    """Commit of the project checkout (``+dirty`` with local changes), or 'unknown'."""
    try:
        out = subprocess.run(["git", "-C", str(project_root()), "rev-parse", "HEAD"], capture_output=True, text=True,
                             timeout=5, check=False)
        dirty = subprocess.run(["git", "-C", str(project_root()), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5, check=False)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return (out.stdout.strip() or "unknown") + ("+dirty" if dirty.stdout.strip() else "")


def parse_epoch(text: str | None, *, file: str | None = None, key: str = "scenario.start_utc") -> int:
    """UTC (ns since 1970) of an ISO 8601 time such as ``2025-06-01T00:00:00Z``."""
    raw = str(text or DEFAULT_EPOCH)
    try:
        when = _dt.datetime.fromisoformat(raw.replace("Z", "+00:00"))
    except ValueError:
        raise ConfigError(f"expected an ISO 8601 time such as {DEFAULT_EPOCH!r}, found {raw!r}", file=file,
                          key=key) from None
    if when.tzinfo is None:
        when = when.replace(tzinfo=_dt.UTC)
    whole = when.replace(microsecond=0)
    return int(whole.timestamp()) * 1_000_000_000 + when.microsecond * 1000


def host_metadata() -> dict[str, Any]:
    """Versions and host, for ``run_start``."""
    return {
        "bench_version": __version__,
        "git_commit": git_commit(),
        "host": platform.node(),
        "python": platform.python_version(),
        "numpy": np.__version__,
    }
