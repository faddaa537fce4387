"""What every result object offers a notebook user: a short repr, a JSON-safe dict, ``save``.

A result class (a dataclass of the analysis' outputs) inherits :class:`Result`, is declared
with ``@dataclass(repr=False)`` (a generated repr would print every array) and writes two
small methods:

``_headline() -> str``
    the few numbers a person wants to see first, with units (shown by ``repr``);
``_record() -> dict``
    the result as plain data, SI units in the key names (``_hz``, ``_m``, ``_j``).

:meth:`Result.to_dict` turns the record into JSON-safe values (numpy -> Python, NaN/inf ->
``None``, complex -> ``{"re", "im"}``); :meth:`Result.save` writes it, and the arrays a result
names in ``_arrays()``, into a folder, each file whole or not at all.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from .files import atomic_output, null_nonfinite, write_json
from .records import to_jsonable

__all__ = ["Result"]


def _stem(cls: type) -> str:
    # ModalResult -> modal_result, EnsembleStats -> ensemble_stats
    return re.sub(r"(?<!^)(?=[A-Z])", "_", cls.__name__).lower()


class Result:
    """Mixin for result dataclasses: short ``repr``, :meth:`to_dict`, :meth:`save`."""

    def _headline(self) -> str:
        raise NotImplementedError

    def _record(self) -> dict:
        raise NotImplementedError

    def _arrays(self) -> dict:
        """Arrays worth keeping beside the JSON (name -> numpy array); none by default."""
        return {}

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self._headline()})"

    def to_dict(self) -> dict:
        """The result as JSON-safe plain data (SI units; ``None`` where a value is undefined)."""
        return null_nonfinite(to_jsonable(self._record()))

    def save(self, folder: str | os.PathLike, name: str | None = None) -> Path:
        """Write ``<name>.json`` (:meth:`to_dict`) and, if the result has arrays, ``<name>.npz``
        into ``folder`` (created if missing; other files there are left alone).

        ``name`` defaults to the class name in snake case (``modal_result``). Each file is
        written to a temporary name and renamed: it is whole or absent. Returns the JSON path.
        """
        folder = Path(folder)
        stem = name or _stem(type(self))
        folder.mkdir(parents=True, exist_ok=True)
        arrays = self._arrays()
        if arrays:
            import numpy as np

            with atomic_output(folder / f"{stem}.npz") as tmp:
                with open(tmp, "wb") as fh:
                    np.savez_compressed(fh, **{k: np.asarray(v) for k, v in arrays.items()})
        return write_json(folder / f"{stem}.json", self.to_dict())
