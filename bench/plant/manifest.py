"""Trust before native code: an FMU is loaded only when its SHA-256 is in a manifest.

A manifest is a ``SHA256SUMS`` file in ``sha256sum`` format (``<64 hex>  <file name>``
per line). The bench's own build writes ``fmu/build/SHA256SUMS``; for an FMU brought
by a user, a ``SHA256SUMS`` beside it (write it with ``sha256sum X.fmu > SHA256SUMS``) or
an explicit hash in the scenario's ``[plant]`` table. A changed file (rebuilt, tampered
with, truncated) no longer matches and is refused before any of its code runs.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

from bench.errors import PlantError

__all__ = ["sha256_file", "read_manifest", "verify_fmu", "MANIFEST_NAME"]

MANIFEST_NAME = "SHA256SUMS"
_LINE = re.compile(r"^([0-9a-fA-F]{64})\s+\*?(.+?)\s*$")


def sha256_file(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with Path(path).open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def read_manifest(path: str | Path) -> dict[str, str]:
    """``{file name: hex digest}`` from a ``sha256sum``-format file."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise PlantError(f"cannot read FMU manifest {path}: {exc.strerror}") from None
    out: dict[str, str] = {}
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        m = _LINE.match(line)
        if not m:
            raise PlantError(f"{path}: line {n}: expected '<sha256 hex>  <file name>', found {line[:80]!r}")
        out[Path(m.group(2)).name] = m.group(1).lower()
    return out


def verify_fmu(fmu: str | Path, *, manifest: str | Path | None = None, sha256: str | None = None) -> str:
    """Check ``fmu`` against an expected hash; return its digest or raise :class:`PlantError`.

    The expected hash is ``sha256`` when given, else the entry for the FMU's file name in
    ``manifest`` (default: ``SHA256SUMS`` in the FMU's folder).
    """
    fmu = Path(fmu)
    if not fmu.is_file():
        raise PlantError(f"FMU not found: {fmu}")
    actual = sha256_file(fmu)
    if sha256 is not None:
        expected = sha256.strip().lower()
        source = "the given sha256"
    else:
        mpath = Path(manifest) if manifest is not None else fmu.parent / MANIFEST_NAME
        if not mpath.is_file():
            raise PlantError(
                f"{fmu}: no manifest {mpath} to check it against; the bench loads an FMU's native code only "
                f"when its SHA-256 is listed (sha256 {actual})"
            )
        entries = read_manifest(mpath)
        if fmu.name not in entries:
            raise PlantError(f"{fmu}: not listed in {mpath}; refusing to load unlisted native code (sha256 {actual})")
        expected = entries[fmu.name]
        source = str(mpath)
    if actual != expected:
        raise PlantError(
            f"{fmu}: SHA-256 mismatch: {source} expects {expected}, the file has {actual}; "
            "the FMU was changed after it was listed (rebuild with 'make fmus' or update the manifest)"
        )
    return actual
