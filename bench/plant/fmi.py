"""The bench's only use of fmpy: model descriptions, validation, and one running FMU.

:func:`read_description` reads ``modelDescription.xml`` (no native code is loaded);
:func:`validate` runs fmpy's schema, naming and model-structure checks;
:class:`FmuInstance` loads the binary of a co-simulation FMU (FMI 2.0 or 3.0), holds one
instance for a whole run and steps it at a fixed communication step. Its hot loop calls
the FMU's ``DoStep`` and bulk ``GetReal``/``GetFloat64`` from compiled code
(:mod:`bench.plant.fmistep`) through the addresses of the functions fmpy has loaded, the
outputs written straight into rows of a numpy buffer: no Python per step.

Native code is loaded only from bytes whose SHA-256 is trusted (:mod:`bench.plant.manifest`):
:class:`FmuInstance` and :func:`simulate` take the :class:`~bench.plant.manifest.FmuTrust`
of a check, or check against the build's manifest themselves, then re-read the file and
extract exactly the bytes they checked.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import shutil
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench.errors import PlantError
from bench.plant.manifest import FmuTrust, extract_trusted

__all__ = ["Variable", "FmuDescription", "read_description", "validate", "simulate", "FmuInstance"]


@dataclass(frozen=True)
class Variable:
    """One model variable as the model description declares it."""

    name: str
    vr: int
    type: str  # Float64, Int32, Boolean, String, ... (FMI 2.0 Real -> Float64, Integer -> Int32)
    causality: str
    variability: str
    unit: str | None
    start: Any
    description: str
    min: Any = None
    max: Any = None


@dataclass
class FmuDescription:
    """What an FMU declares about itself."""

    path: Path
    fmi_version: str
    model_name: str
    identifier: str
    description: str
    generation_tool: str
    co_simulation: bool
    variables: dict[str, Variable] = field(default_factory=dict)
    default_experiment: dict[str, float] = field(default_factory=dict)

    def of_causality(self, causality: str) -> list[Variable]:
        """Variables with the given causality, in value-reference order."""
        return sorted((v for v in self.variables.values() if v.causality == causality), key=lambda v: v.vr)


_TYPES = {"Real": "Float64", "Integer": "Int32", "Enumeration": "Int32"}


def read_description(path: str | Path) -> FmuDescription:
    """Parse an FMU's model description; :class:`PlantError` if it cannot be read."""
    from fmpy import read_model_description

    path = Path(path)
    if not path.exists():
        raise PlantError(f"FMU not found: {path}")
    try:
        md = read_model_description(str(path), validate=False)
    except Exception as exc:  # fmpy raises plain exceptions for unreadable archives
        raise PlantError(f"{path}: cannot read modelDescription.xml: {exc}") from None
    cs = md.coSimulation
    variables = {}
    for v in md.modelVariables:
        variables[v.name] = Variable(
            name=v.name,
            vr=int(v.valueReference),
            type=_TYPES.get(v.type, v.type),
            causality=v.causality or "local",
            variability=v.variability or "continuous",
            unit=(v.declaredType.unit if v.unit is None and v.declaredType is not None else v.unit),
            start=v.start,
            description=v.description or "",
            min=v.min,
            max=v.max,
        )
    de = {}
    if md.defaultExperiment is not None:
        for key in ("startTime", "stopTime", "stepSize", "tolerance"):
            value = getattr(md.defaultExperiment, key, None)
            if value is not None:
                de[key] = float(value)
    return FmuDescription(
        path=path,
        fmi_version=md.fmiVersion,
        model_name=md.modelName,
        identifier=cs.modelIdentifier if cs is not None else "",
        description=md.description or "",
        generation_tool=md.generationTool or "",
        co_simulation=cs is not None,
        variables=variables,
        default_experiment=de,
    )


def validate(path: str | Path) -> list[str]:
    """fmpy's validation of the model description: a list of problems (empty when valid)."""
    from fmpy.validation import validate_fmu

    return list(validate_fmu(str(path)))


@contextlib.contextmanager
def _keep_cwd() -> Iterator[None]:
    """Restore the working directory: fmpy changes into the FMU's binary folder to load it
    and stays there when the load fails (a corrupted library), a folder removed next."""
    cwd = os.getcwd()
    try:
        yield
    finally:
        if os.getcwd() != cwd:
            os.chdir(cwd)


def simulate(
    path: str | Path, stop_time: float, step: float, outputs: list[str] | None = None, *, trust: FmuTrust | None = None
) -> np.ndarray:
    """A run with ``fmpy.simulate_fmu`` of the trusted bytes of ``path`` (see the module
    docstring). fmpy's validation is not repeated here (:func:`validate` reports it): a model
    description the validator objects to may still describe an FMU that runs."""
    from fmpy import simulate_fmu

    folder = extract_trusted(Path(path), trust)
    try:
        with _keep_cwd():
            return simulate_fmu(
                folder, stop_time=stop_time, output_interval=step, step_size=step, output=outputs, validate=False
            )
    except Exception as exc:
        raise PlantError(f"{path}: simulation with fmpy failed: {exc}") from None
    finally:
        shutil.rmtree(folder, ignore_errors=True)


class FmuInstance:
    """One instance of a co-simulation FMU, stepped at a fixed communication step.

    Parameters
    ----------
    desc:
        The FMU's description (from :func:`read_description`).
    instance_name:
        Name passed to the FMU (shows in its log messages).
    trust:
        The FMU's checked SHA-256 (:func:`~bench.plant.manifest.verify_fmu`); without it
        :meth:`open` checks the file against the build's manifest.

    Use as a context manager; :meth:`close` terminates and frees the instance and removes
    the extracted files, and may be called more than once.
    """

    def __init__(self, desc: FmuDescription, instance_name: str = "bench", *, trust: FmuTrust | None = None):
        if not desc.co_simulation:
            raise PlantError(f"{desc.path}: not a co-simulation FMU (model exchange is not supported)")
        if desc.fmi_version not in ("2.0", "3.0"):
            raise PlantError(f"{desc.path}: FMI {desc.fmi_version} is not supported (2.0 or 3.0)")
        self.desc = desc
        self.trust = trust
        self.log: list[str] = []
        self._name = instance_name
        self._dir: str | None = None
        self._fmu: Any = None
        self._state = "closed"
        self._buffer: np.ndarray | None = None
        self._vr_array: np.ndarray | None = None
        self._flags = np.zeros(3, np.uint8)
        self._addr: tuple[int, int, int] | None = None

    # -- life cycle --------------------------------------------------------------------
    def open(self, start_time: float = 0.0) -> FmuInstance:
        """Check, extract, load and instantiate; the instance is then in initialization mode."""
        self._dir = extract_trusted(self.desc.path, self.trust)
        v3 = self.desc.fmi_version == "3.0"
        cwd = os.getcwd()
        try:
            md_guid = self._guid()
            if v3:
                from fmpy.fmi3 import FMU3Slave, fmi3LogMessageCallback

                self._fmu = FMU3Slave(
                    guid=md_guid, unzipDirectory=self._dir, modelIdentifier=self.desc.identifier,
                    instanceName=self._name,
                )

                def log3(env, status, category, message):
                    self.log.append(f"[{_STATUS[status]}] {(message or b'').decode(errors='replace')}")

                self._cb = fmi3LogMessageCallback(log3)
                self._fmu.instantiate(loggingOn=False, logMessage=log3)
                self._fmu.enterInitializationMode(startTime=start_time)
            else:
                from fmpy import calloc, free
                from fmpy.fmi2 import (
                    FMU2Slave,
                    fmi2CallbackAllocateMemoryTYPE,
                    fmi2CallbackFreeMemoryTYPE,
                    fmi2CallbackFunctions,
                    fmi2CallbackLoggerTYPE,
                )

                self._fmu = FMU2Slave(
                    guid=md_guid, unzipDirectory=self._dir, modelIdentifier=self.desc.identifier,
                    instanceName=self._name,
                )

                def log2(env, name, status, category, message):
                    self.log.append(f"[{_STATUS[status]}] {(message or b'').decode(errors='replace')}")

                cb = fmi2CallbackFunctions()
                cb.logger = fmi2CallbackLoggerTYPE(log2)
                cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
                cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
                self._cb = cb
                self._fmu.instantiate(callbacks=cb, loggingOn=False)
                self._fmu.setupExperiment(startTime=start_time)
                self._fmu.enterInitializationMode()
        except PlantError:
            self.close()
            raise
        except Exception as exc:
            msg = self._fail_message(f"cannot instantiate: {exc}")
            self.close()
            raise PlantError(msg) from None
        finally:
            if os.getcwd() != cwd:  # fmpy stays in the binary folder when the load fails
                os.chdir(cwd)
        self._state = "init"
        return self

    def _guid(self) -> str:
        from fmpy import read_model_description

        assert self._dir is not None
        return read_model_description(self._dir, validate=False).guid

    def exit_initialization(self) -> None:
        """Leave initialization mode (parameters are fixed from here on)."""
        try:
            self._fmu.exitInitializationMode()
        except Exception as exc:
            raise PlantError(self._fail_message(f"initialization failed: {exc}")) from None
        self._state = "step"

    def close(self) -> None:
        """Terminate and free the instance, unload the library, remove extracted files."""
        fmu, self._fmu = self._fmu, None
        if fmu is not None:
            try:
                if self._state == "step":
                    fmu.terminate()
            except Exception:  # a failed FMU may refuse to terminate; free it all the same
                pass
            with contextlib.suppress(Exception):
                fmu.freeInstance()
        self._state = "closed"
        self._buffer = None
        self._addr = None
        if self._dir is not None:
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None

    def __enter__(self) -> FmuInstance:
        return self if self._state != "closed" else self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _fail_message(self, what: str) -> str:
        tail = "; ".join(self.log[-5:])
        return f"{self.desc.path.name}: {what}" + (f" (FMU log: {tail})" if tail else "")

    # -- variables ---------------------------------------------------------------------
    def set(self, values: dict[str, float | int]) -> None:
        """Set variables by name (Float64/Real and Int32/Integer)."""
        v3 = self.desc.fmi_version == "3.0"
        for name, value in values.items():
            var = self.desc.variables.get(name)
            if var is None:
                raise PlantError(f"{self.desc.path.name}: no variable {name!r}")
            try:
                if var.type == "Float64":
                    (self._fmu.setFloat64 if v3 else self._fmu.setReal)([var.vr], [float(value)])
                elif var.type == "Int32":
                    (self._fmu.setInt32 if v3 else self._fmu.setInteger)([var.vr], [round(value)])
                else:
                    raise PlantError(
                        f"{self.desc.path.name}: variable {name!r} is {var.type}; expected Float64 or Int32"
                    )
            except PlantError:
                raise
            except Exception as exc:
                raise PlantError(self._fail_message(f"setting {name} = {value!r} failed: {exc}")) from None

    def get(self, names: list[str]) -> list[float]:
        """Current values of Float64/Real variables by name."""
        vrs = [self._real(n).vr for n in names]
        try:
            return list(self._fmu.getFloat64(vrs) if self.desc.fmi_version == "3.0" else self._fmu.getReal(vrs))
        except Exception as exc:
            raise PlantError(self._fail_message(f"reading {names} failed: {exc}")) from None

    def _real(self, name: str) -> Variable:
        var = self.desc.variables.get(name)
        if var is None:
            raise PlantError(f"{self.desc.path.name}: no variable {name!r}")
        if var.type != "Float64":
            raise PlantError(f"{self.desc.path.name}: output {name!r} is {var.type}; expected Float64/Real")
        return var

    # -- stepping ----------------------------------------------------------------------
    def bind_outputs(self, names: list[str], buffer: np.ndarray) -> None:
        """Read ``names`` after every step into the rows of ``buffer`` (rows, len(names))."""
        if buffer.dtype != np.float64 or not buffer.flags.c_contiguous or buffer.shape[1] != len(names):
            raise ValueError("buffer must be C-contiguous float64 of shape (rows, len(names))")
        vrs = [self._real(n).vr for n in names]
        self._vr_array = np.asarray(vrs, dtype=np.uint32)
        self._buffer = buffer

    def advance(self, step0: int, n: int, h: float, row0: int = 0) -> None:
        """Run ``n`` steps of ``h`` seconds from communication point ``step0 * h``,
        writing the bound outputs after step k into row ``row0 + k`` of the buffer.

        The steps run in compiled code (:mod:`bench.plant.fmistep`) through the addresses of
        the FMU's own functions. Raises :class:`PlantError` with the FMU's own messages when
        a step fails.
        """
        if self._state != "step":
            raise PlantError(f"{self.desc.path.name}: not in step mode (state {self._state})")
        if n <= 0:
            return
        rows = 0 if self._buffer is None else self._buffer.shape[0]
        if row0 < 0 or row0 + n > rows:
            raise ValueError(f"rows {row0}..{row0 + n - 1} are outside the bound buffer of {rows} rows")
        from bench.plant import fmistep

        fn = self._compiled()
        assert self._buffer is not None and self._vr_array is not None
        if self.desc.fmi_version == "3.0":
            done, status, what = fmistep.advance3(fn[0], fn[1], fn[2], step0, n, h, self._vr_array, self._buffer, row0,
                                                  self._flags)
            term, early = bool(self._flags[1]), bool(self._flags[2])
            get_name = "fmi3GetFloat64"
        else:
            done, status, what = fmistep.advance2(fn[0], fn[1], fn[2], step0, n, h, self._vr_array, self._buffer, row0)
            term = early = False
            get_name = "fmi2GetReal"
        if done == n:
            return
        if what == 0:
            self._step_failed(status, (step0 + done) * h, term, early)
        raise PlantError(self._fail_message(f"{get_name} failed at t = {(step0 + done + 1) * h:.6f} s"))

    def _compiled(self) -> tuple[int, int, int]:
        """The addresses of DoStep, the bulk Float64/Real getter and the instance."""
        if self._addr is None:
            dll = self._fmu.dll
            v3 = self.desc.fmi_version == "3.0"
            do_step = dll.fmi3DoStep if v3 else dll.fmi2DoStep
            get = dll.fmi3GetFloat64 if v3 else dll.fmi2GetReal
            comp = self._fmu.component
            comp = comp if isinstance(comp, int) else ctypes.cast(comp, ctypes.c_void_p).value
            addr = ctypes.cast(do_step, ctypes.c_void_p).value, ctypes.cast(get, ctypes.c_void_p).value
            self._addr = (addr[0] or 0, addr[1] or 0, comp or 0)
        return self._addr

    def _step_failed(self, status: int, t: float, terminate: bool, early: bool) -> None:
        self._state = "failed"
        name = _STATUS.get(status, str(status))
        if status > 1:
            why = f"returned {name}"
        else:
            why = "asked to terminate the simulation" if terminate else "returned early"
        raise PlantError(self._fail_message(f"doStep at t = {t:.6f} s {why}"))


_STATUS = {0: "OK", 1: "Warning", 2: "Discard", 3: "Error", 4: "Fatal", 5: "Pending"}
