"""Topic specifications: what a producer of samples declares about its records.

Producers (truth, sensor models, links) describe their columnar records with a
:class:`TopicSpec`; the recorder turns it into an MCAP channel. Kept free of any
dependency so that every layer can use it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["TopicSpec"]


@dataclass(frozen=True)
class TopicSpec:
    """A columnar topic: name, schema name, record dtype (with ``t_ns``), units, text."""

    topic: str
    schema: str
    dtype: np.dtype
    description: str = ""
    units: dict[str, str] = field(default_factory=dict)
