"""Run an FMU instance directly (physics tests of the vehicle models)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.plant.fmi import FmuInstance, read_description
from bench.plant.manifest import FmuTrust


def run_fmu(
    path: Path,
    seconds: float,
    outputs: list[str],
    *,
    inputs: dict[str, float] | None = None,
    params: dict[str, float] | None = None,
    changes: dict[float, dict[str, float]] | None = None,
    h: float = 1e-3,
    trust: FmuTrust | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Times (N,) and outputs (N, len(outputs)) after each step; ``changes`` set inputs at times;
    ``trust``: the FMU's checked hash (default: the build's manifest must list it)."""
    desc = read_description(path)
    n = round(seconds / h)
    buf = np.empty((n, len(outputs)))
    cuts = sorted((round(t / h), v) for t, v in (changes or {}).items())
    with FmuInstance(desc, trust=trust).open() as inst:
        inst.set(params or {})
        inst.set(inputs or {})
        inst.exit_initialization()
        inst.bind_outputs(outputs, buf)
        step = 0
        for k, values in [*cuts, (n, {})]:
            if k > step:
                inst.advance(step, k - step, h, step)
                step = k
            if values:
                inst.set(values)
    return (np.arange(n) + 1) * h, buf
