"""Trust before native code: an FMU is loaded only when its SHA-256 is known in advance.

The expected hash comes from one of two places, never from a file beside the FMU (anyone
who can change the FMU can write a matching ``SHA256SUMS`` next to it):

- the build's manifest, ``fmu/build/SHA256SUMS`` under the bench's own project root
  (:func:`bench.paths.fmu_dir`), written by ``fmu/build.py`` for the FMUs it built: an
  FMU whose digest it lists is one the build made, wherever it was copied;
- the test case or scenario: ``sha256 = "<64 hex>"`` in ``[plant]`` next to the FMU path
  (or ``bench fmu check --sha256``).

A changed file (rebuilt, tampered with, truncated) no longer matches and is refused with
:class:`~bench.errors.ConfigError` naming the file, the expected and the found hash,
before any of its code runs. Only an explicit opt-in (``trust = "unverified"`` in
``[plant]``, ``bench fmu check --trust-fmu``) loads an FMU with no trusted hash; the
:class:`FmuTrust` it yields says so, and the run records it.

:func:`trusted_bytes` re-reads the file at load time and checks those very bytes, so the
file cannot be swapped between the check and the load.
"""

from __future__ import annotations

import hashlib
import io
import re
import shutil
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path

from bench.errors import ConfigError, PlantError
from bench.paths import fmu_dir

__all__ = ["FmuTrust", "sha256_file", "read_manifest", "build_manifest", "verify_fmu", "trusted_bytes",
           "MANIFEST_NAME", "extract_trusted"]

MANIFEST_NAME = "SHA256SUMS"
_LINE = re.compile(r"^([0-9a-fA-F]{64})\s+\*?(.+?)\s*$")
_HEX = re.compile(r"^[0-9a-f]{64}$")


@dataclass(frozen=True)
class FmuTrust:
    """Why an FMU may run: its digest and where the expected one came from.

    ``verified`` is False only for an explicit opt-in to an FMU without a trusted hash.
    """

    path: Path
    sha256: str
    source: str
    verified: bool = True

    def record(self) -> dict[str, str]:
        """What a recording's metadata says about it."""
        return {"fmu_sha256": self.sha256, "fmu_trust": self.source, "fmu_verified": str(self.verified).lower()}


def sha256_file(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with Path(path).open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def build_manifest() -> Path:
    """The manifest the bench's build writes: ``fmu/build/SHA256SUMS``."""
    return fmu_dir() / "build" / MANIFEST_NAME


def read_manifest(path: str | Path) -> dict[str, str]:
    """``{file name: hex digest}`` from a ``sha256sum``-format file."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise PlantError(f"cannot read FMU manifest {path}: {exc}") from None
    out: dict[str, str] = {}
    for n, line in enumerate(text.splitlines(), 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        m = _LINE.match(line)
        if not m:
            raise PlantError(f"{path}: line {n}: expected '<sha256 hex>  <file name>', found {line[:80]!r}")
        out[Path(m.group(2)).name] = m.group(1).lower()
    return out


def _expected_hash(sha256: object, where: str) -> str:
    if not isinstance(sha256, str) or not _HEX.match(sha256.strip().lower()):
        raise ConfigError(f"expected the FMU's SHA-256 as 64 hex digits, found {sha256!r}", file=where or None)
    return sha256.strip().lower()


def verify_fmu(fmu: str | Path, *, sha256: str | None = None, where: str = "", unverified: bool = False) -> FmuTrust:
    """Check ``fmu`` against its trusted hash; the :class:`FmuTrust` or :class:`ConfigError`.

    Parameters
    ----------
    fmu:
        The .fmu file.
    sha256:
        Expected digest from the test case or scenario (``where`` names it); without it,
        the build's manifest must list the file's digest.
    unverified:
        The user's explicit opt-in: an FMU with no trusted hash is let through (a
        mismatch with a given ``sha256`` still is not), marked unverified.
    """
    fmu = Path(fmu)
    if not fmu.is_file():
        raise ConfigError("FMU not found (or not a regular file)", file=str(fmu))
    actual = sha256_file(fmu)
    if sha256 is not None:
        expected = _expected_hash(sha256, where)
        source = f"sha256 given in {where}" if where else "the given sha256"
        if actual != expected:
            raise ConfigError(
                f"SHA-256 mismatch: {source} expects {expected}, the file has {actual}; refusing to load its native "
                "code (the FMU is not the one the case names)", file=str(fmu))
        return FmuTrust(fmu, actual, source)
    manifest = build_manifest()
    entries = read_manifest(manifest) if manifest.is_file() else {}
    if actual in entries.values():
        return FmuTrust(fmu, actual, f"the build manifest {manifest}")
    beside = fmu.parent / MANIFEST_NAME
    ignored = (f"; the {MANIFEST_NAME} beside it is not trusted (whoever can change the FMU can write it)"
               if beside.is_file() and beside.resolve() != manifest.resolve() else "")
    if unverified:
        return FmuTrust(fmu, actual, f"unverified: no trusted SHA-256, loaded by the user's explicit opt-in{ignored}",
                        verified=False)
    if fmu.name in entries:
        raise ConfigError(
            f"SHA-256 mismatch: the build manifest {manifest} expects {entries[fmu.name]} for {fmu.name}, the file has "
            f"{actual}; refusing to load its native code (rebuild with 'make fmus' if the build changed it){ignored}",
            file=str(fmu))
    raise ConfigError(
        f"no trusted SHA-256 for this FMU (it has {actual}): it is not one the build made (not in {manifest}) and "
        f"no sha256 was given{ignored}; give sha256 = \"<hex>\" in the scenario's [plant] table, or opt in with "
        "trust = \"unverified\"", file=str(fmu))


def trusted_bytes(trust: FmuTrust) -> bytes:
    """The FMU's bytes, read now and checked against ``trust`` (a file changed since the
    check is refused); an unverified opt-in returns the bytes as they are."""
    try:
        data = trust.path.read_bytes()
    except OSError as exc:
        raise PlantError(f"{trust.path}: cannot read the FMU: {exc.strerror}") from None
    if trust.verified and hashlib.sha256(data).hexdigest() != trust.sha256:
        raise PlantError(f"{trust.path}: the file changed after its SHA-256 was checked ({trust.source}); "
                         "refusing to load its native code")
    return data


def extract_trusted(path: Path, trust: FmuTrust | None) -> str:
    """A temporary folder holding the FMU's contents, unpacked from bytes checked against
    ``trust`` (by default: the build's manifest); the caller removes it."""
    trust = trust if trust is not None else verify_fmu(path)
    if Path(trust.path).resolve() != Path(path).resolve():
        raise PlantError(f"{path}: the trust given is for another file ({trust.path})")
    data = trusted_bytes(trust)
    folder = tempfile.mkdtemp(prefix="bench_fmu_")
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            zf.extractall(folder)
    except (zipfile.BadZipFile, OSError, ValueError) as exc:
        shutil.rmtree(folder, ignore_errors=True)
        raise PlantError(f"{path}: cannot unpack the FMU: {exc}") from None
    return folder
