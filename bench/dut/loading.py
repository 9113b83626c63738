"""``[dut] name = "package.module:Class"``: an estimator found by its module, no installation.

:func:`from_module` imports the module -- its top-level package from the first search
folder that has it (the test case's folder), else from the Python path -- and returns the
attribute if it is an :class:`~bench.dut.estimator.Estimator` subclass or a factory. A
module of the same name beside another case, imported for an earlier run, is replaced;
one that would shadow a module already imported from elsewhere is refused. Anything that
names no estimator is a :class:`~bench.errors.ConfigError` with key ``dut.name``; a module
that is there but fails while it is imported raises what it raised (the estimator failing
to start).
"""

from __future__ import annotations

import inspect
import sys
from collections.abc import Callable
from importlib import import_module
from importlib.machinery import PathFinder
from importlib.util import module_from_spec
from pathlib import Path
from types import ModuleType
from typing import Any

from bench.dut.estimator import Estimator
from bench.errors import ConfigError

__all__ = ["from_module"]

#: Top-level modules imported from a search folder: name -> the file they came from.
_FROM_FOLDER: dict[str, str] = {}


def from_module(name: str, search: list[Path]) -> Callable[[], Estimator]:
    """The estimator class or factory ``package.module:Attr`` (see :func:`~bench.dut.estimator.create_estimator`)."""
    mod_name, _, attr = name.partition(":")
    if not all(p.isidentifier() for p in mod_name.split(".")) or not all(p.isidentifier() for p in attr.split(".")):
        raise ConfigError(f"expected package.module:Class, found {name!r}", key="dut.name")
    module = _import(mod_name, search, name)
    obj: Any = module
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise ConfigError(
                f"the module {mod_name!r} ({getattr(module, '__file__', None) or 'built in'}) has no {attr!r}",
                key="dut.name",
            ) from None
    if isinstance(obj, type):
        if not issubclass(obj, Estimator):
            raise ConfigError(f"{name!r} is a class that is not a subclass of bench.dut.Estimator", key="dut.name")
        if inspect.isabstract(obj):
            missing = ", ".join(sorted(getattr(obj, "__abstractmethods__", ())))
            raise ConfigError(f"{name!r} is an abstract class: it does not implement {missing}", key="dut.name")
    elif not callable(obj):
        raise ConfigError(
            f"{name!r} is a {type(obj).__name__}, not an Estimator subclass or a factory returning one",
            key="dut.name",
        )
    return obj


def _import(mod_name: str, search: list[Path], name: str) -> ModuleType:
    """Module ``mod_name``: its top-level package from the first search folder that has
    it (loaded again when an earlier run took it from another folder), else from the
    Python path."""
    top = mod_name.partition(".")[0]
    for folder in search:
        spec = PathFinder.find_spec(top, [str(folder)])
        if spec is None or spec.origin is None:
            continue
        loaded = sys.modules.get(top)
        if loaded is not None and getattr(loaded.__spec__, "origin", None) != spec.origin:
            if top not in _FROM_FOLDER:
                raise ConfigError(
                    f"the module {top!r} beside the test case ({spec.origin}) has the name of one already "
                    f"imported from {getattr(loaded, '__file__', None) or 'the Python path'}: rename it",
                    key="dut.name",
                )
            for key in [k for k in sys.modules if k == top or k.startswith(top + ".")]:
                del sys.modules[key]  # a module of that name from another case's folder
            loaded = None
        if loaded is None:
            module = module_from_spec(spec)
            sys.modules[top] = module
            try:
                spec.loader.exec_module(module)  # type: ignore[union-attr]
            except BaseException:
                del sys.modules[top]
                raise
            _FROM_FOLDER[top] = spec.origin
        break
    try:
        return import_module(mod_name)
    except ModuleNotFoundError as exc:
        if exc.name is None or not (mod_name == exc.name or mod_name.startswith(exc.name + ".")):
            raise  # a module the estimator's own module imports is missing: the estimator fails to start
        where = "".join(f"{d}, " for d in search)
        raise ConfigError(
            f"no module {exc.name!r} for the estimator {name!r} (looked in {where}then the Python path)",
            key="dut.name",
        ) from None
