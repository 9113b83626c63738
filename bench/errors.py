"""The bench's exception hierarchy.

One root, :class:`BenchError`, split by the stage that failed. Messages say what was
expected and what was found, and name the file and the field when there is one.
"""

from __future__ import annotations

__all__ = [
    "BenchError",
    "ConfigError",
    "PlantError",
    "LinkError",
    "CodecError",
    "DutError",
    "RecordingError",
]


class BenchError(Exception):
    """Root of every error the bench raises on purpose."""


class ConfigError(BenchError):
    """A configuration file or argument is wrong.

    Parameters
    ----------
    message:
        What was expected and what was found.
    file:
        The file the value came from, if any.
    key:
        The dotted key of the offending field, if any (``segment[3].speed``).
    """

    def __init__(self, message: str, *, file: str | None = None, key: str | None = None):
        self.file = file
        self.key = key
        self.reason = message
        where = ": ".join(part for part in (file, key) if part)
        super().__init__(f"{where}: {message}" if where else message)


class PlantError(BenchError):
    """The plant (motion script or FMU) could not produce the motion asked of it."""


class LinkError(BenchError):
    """A bus or serial link could not be opened, or was lost."""


class CodecError(BenchError):
    """A frame or sentence could not be decoded (bad CRC, counter, length, checksum).

    ``kind`` is a short machine-readable name that links count by.
    """

    def __init__(self, kind: str, message: str):
        self.kind = kind
        super().__init__(f"{kind}: {message}")


class DutError(BenchError):
    """The estimator under test crashed, hung, never started or misbehaved on the link.

    ``certain`` (the default) says the failure is the DUT's: the run ends ``dut_failed`` and
    is judged FAIL. ``certain=False`` is for an ending the bench cannot pin on the DUT (a
    SIGKILL the bench did not send, which the kernel's OOM killer or an operator may have
    sent; a ``MemoryError`` in an estimator sharing the bench's process): the run ends
    ``dut_error``, judged ERROR, and the message says why the bench cannot tell.
    """

    def __init__(self, message: str, *, certain: bool = True):
        self.certain = certain
        super().__init__(message)


class RecordingError(BenchError):
    """A recording could not be written or read."""
