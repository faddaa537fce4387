"""Package APIs that load on first use (PEP 562), so importing a package stays light."""

from __future__ import annotations

import sys
from importlib import import_module

__all__ = ["exports"]


def exports(package: str, where: dict[str, str]):
    """``__getattr__`` and ``__dir__`` for ``package`` whose public names live in submodules.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    where : dict
        Public name -> the module that defines it: a submodule of ``package`` (``"stats"``) or,
        with a dot, an absolute module (``"rpud_common.errors"``); ``"plots:admittance"`` exports
        that module's ``admittance`` under the public name.

    Returns
    -------
    tuple
        ``(__getattr__, __dir__)`` to assign at the package's top level.
    """
    def __getattr__(name):
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        mod, _, attr = where[name].partition(":")
        value = getattr(import_module(mod) if "." in mod else import_module(f".{mod}", package), attr or name)
        setattr(sys.modules[package], name, value)     # later lookups skip this function
        return value

    def __dir__():
        return sorted(set(vars(sys.modules[package])) | set(where))

    return __getattr__, __dir__
