"""Where a run's outgoing traffic comes from: the :class:`TrafficProvider` seam, and the
synthesized source (:class:`SynthProvider`). Replays of recordings and field logs are
providers too (:mod:`bench.run.replay`, :mod:`bench.run.logreplay`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod

from bench.record.mcap_io import RecordingWriter
from bench.run.source import RunSource
from bench.run.spec import RunSpec
from bench.run.traffic import Traffic, TrafficEncoder
from bench.runinfo import parse_epoch

__all__ = ["TrafficProvider", "SynthProvider", "COMMANDS_TOPIC"]

COMMANDS_TOPIC = "/bench/commands"
_COMMAND_NAMES = {1: "grid", 2: "geographic", 3: "reset"}


class TrafficProvider(ABC):
    """Where a run's outgoing traffic comes from, window by window.

    :class:`SynthProvider` synthesizes it from a scenario (truth, sensors, ICD encoding,
    wire faults); the replay providers of :mod:`bench.run.replay` read it from a recording
    or from field logs. A provider declares and writes its own topics (truth, samples,
    faults) and returns the traffic due in each window.
    """

    duration_ns: int
    epoch_ns: int
    #: Bench time the run starts at (a replay may seek); traffic at exactly this time is due.
    start_ns: int = 0

    @abstractmethod
    def metadata(self) -> dict[str, str]:
        """Facts of the source for ``run_start``."""

    @abstractmethod
    def declare(self, rec: RecordingWriter) -> None:
        """Declare topics and write the once-per-run records."""

    @abstractmethod
    def window(self, rec: RecordingWriter, t0_ns: int, t1_ns: int) -> Traffic:
        """Record what the source records for ``(t0, t1]`` and return the traffic due then."""

    def counts(self) -> dict[str, int]:
        """Samples written per topic."""
        return {}


class SynthProvider(TrafficProvider):
    """Traffic synthesized from a :class:`RunSpec`'s scenario, sensors and faults."""

    def __init__(self, spec: RunSpec):
        self.spec = spec
        self.source = RunSource(
            spec.scenario,
            spec.tables,
            spec.seed,
            spec.schedule,
            trajectory=spec.trajectory,
            truth_rate_hz=spec.truth_rate_hz,
            duration_ns=spec.duration_ns,
            write_ideal=spec.write_ideal,
        )
        self.epoch_ns = parse_epoch(spec.scenario.meta.get("start_utc"), file=str(spec.scenario.path))
        self.encoder = TrafficEncoder(
            self.source.models,
            epoch_ns=self.epoch_ns,
            lockstep=spec.clock.lockstep,
            schedule=spec.schedule,
            seed=spec.seed,
            commands=spec.commands,
            talker=spec.links.talker,
        )
        self.duration_ns = self.source.duration_ns

    def metadata(self) -> dict[str, str]:
        return self.source.metadata()

    def declare(self, rec: RecordingWriter) -> None:
        attach = not any(a[0].startswith("scenario/") for a in self.spec.attachments)
        self.source.declare(rec, attach_scenario=attach)
        rec.json_topic(COMMANDS_TOPIC, "bench.Command", {"type": "object"})
        for t, c in self.spec.commands:
            rec.write_json(COMMANDS_TOPIC, t, {"t_ns": t, "command": _COMMAND_NAMES.get(c, str(c)), "code": c})

    def window(self, rec: RecordingWriter, t0_ns: int, t1_ns: int) -> Traffic:
        return self.encoder.window(self.source.produce(rec, t0_ns, t1_ns), t0_ns, t1_ns)

    def counts(self) -> dict[str, int]:
        return dict(self.source.stats.counts)
