"""Lazy attributes of a package (PEP 562): a name is imported from its module on first use.

``import flowtwin`` (and ``import flowtwin.batch``) then costs only what is used: the numerical
stack (numpy, numba, scipy), dask or OpenCV load when an entry point that needs them is first
touched, not when the package is imported.
"""

from __future__ import annotations

import importlib

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing
if TYPE_CHECKING:
    from collections.abc import Callable, Mapping

__all__ = ["lazy_exports"]


def lazy_exports(package: str, exports: Mapping[str, str]
                 ) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for ``package`` that import ``exports[name]`` (a module
    path) the first time ``package.name`` is read.

    Parameters
    ----------
    package
        The package's ``__name__``.
    exports
        Attribute name -> module that defines it (``"module:name"`` when the module calls it
        differently).

    Returns
    -------
    (getattr, dir)
        Functions to assign to the package's ``__getattr__`` and ``__dir__``.
    """
    namespace = importlib.import_module(package).__dict__

    def get(name: str) -> object:
        where = exports.get(name)
        if where is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, _, attr = where.partition(":")
        value = getattr(importlib.import_module(module), attr or name)
        namespace[name] = value  # later reads skip this function
        return value

    def listing() -> list[str]:
        return sorted({*namespace, *exports})

    return get, listing
