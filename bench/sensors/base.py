"""The sensor seam: a model that turns truth into samples over consecutive windows."""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from bench.scenario.trajectory import Trajectory
from bench.topics import TopicSpec

__all__ = ["SensorModel"]


class SensorModel(ABC):
    """A sensor driven window by window through a run.

    :meth:`run` is called for consecutive windows ``(t0_ns, t1_ns]`` in time order and
    returns the records of every sample whose time of validity falls in the window, per
    topic. State (noise processes, pulse residuals) carries over between windows, so the
    output does not depend on how the run is cut into windows.
    """

    #: Instance name: stream name of its random processes and prefix of its topics.
    name: str

    @abstractmethod
    def topics(self) -> list[TopicSpec]:
        """The columnar topics this sensor writes."""

    @abstractmethod
    def run(self, traj: Trajectory, t0_ns: int, t1_ns: int) -> dict[str, np.ndarray]:
        """Records of the samples in ``(t0_ns, t1_ns]``, keyed by topic."""
