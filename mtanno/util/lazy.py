"""Submodules loaded on attribute access (PEP 562), as scipy and librosa do: after a bare
``import mtanno``, ``mtanno.annotate.load_class_config`` or ``mtanno.features.store.read_features``
resolve, and each loads only the modules it needs (``import mtanno`` stays light).

Imports only the standard library, so any package ``__init__`` can use it.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any


def submodule_getattr(package: str,
                      names: Callable[[str], Any] | None = None) -> Callable[[str], Any]:
    """A module ``__getattr__`` for ``package``: ``names(name)`` first (a package's lazily
    attached public names; it raises :class:`AttributeError` for others), then the
    submodule ``package.name`` imported on first use."""

    def __getattr__(name: str) -> Any:
        if names is not None:
            try:
                return names(name)
            except AttributeError:
                pass
        if not name.startswith("__"):
            full = f"{package}.{name}"
            try:
                return importlib.import_module(full)
            except ModuleNotFoundError as exc:
                if exc.name != full:  # the submodule exists; something it imports is missing
                    raise
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__


def lazy_exports(package: str, exports: dict[str, tuple[str, ...]]
                 ) -> tuple[Callable[[str], Any], list[str]]:
    """``(__getattr__, __all__)`` of a package whose public names live in its modules
    (``exports``: module → names) and are attached on first use, so that loading one
    module of the package (a file format, say) does not load the others (numba kernels).
    Unknown names fall back to the submodules (:func:`submodule_getattr`)."""
    module_of = {name: module for module, names in exports.items() for name in names}
    clash = sorted(set(module_of) & set(exports))
    if clash:  # importing the submodule would replace the name by the module
        raise ValueError(f"{package}: names that are also submodules: {clash}")
    namespace = importlib.import_module(package).__dict__

    def attach(name: str) -> Any:
        if name not in module_of:
            raise AttributeError(name)
        value = getattr(importlib.import_module(f"{package}.{module_of[name]}"), name)
        namespace[name] = value  # found directly next time
        return value

    return submodule_getattr(package, attach), sorted(module_of)
