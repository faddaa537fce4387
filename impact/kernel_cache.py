"""Keep numba's on-disk caches of the compiled engines consistent with their sources.

numba stores each ``cache=True`` function's machine code beside its source and checks only that
source file's time stamp before reusing it. An engine loop (:mod:`impact.kernel`) compiles the
building blocks it calls (:mod:`impact.kernel_blocks`, :mod:`impact.event_rules`, the layouts of
:mod:`impact.columns` and :mod:`impact.horn`) into its own machine code, so an edit of a block
alone would leave the loop's cached code stale. :func:`drop_stale` compares one hash of every
compiled source with the hash stored beside the caches and, when they differ, deletes this
package's numba caches (they are rebuilt on first use). The compiled modules import this one
before anything is compiled or loaded.
"""

from __future__ import annotations

import hashlib
import logging
from pathlib import Path

__all__ = ["COMPILED_SOURCES", "drop_stale"]

log = logging.getLogger(__name__)

#: the package's files whose code or constants numba compiles
COMPILED_SOURCES = ("event_rules.py", "columns.py", "horn.py", "kernel_blocks.py", "kernel.py", "kernel_energy.py",
                    "kernel_contact.py", "kernel_modal.py", "rock.py", "drill_kernel.py", "compliant.py",
                    "kernel_compliant.py", "kernel_drill_compliant.py")

_HERE = Path(__file__).resolve().parent
_STAMP = "compiled-sources.sha256"


def _digest() -> str:
    h = hashlib.sha256()
    for name in COMPILED_SOURCES:
        h.update(name.encode())
        h.update((_HERE / name).read_bytes())
    return h.hexdigest()


def drop_stale(cache_dir: Path | None = None) -> bool:
    """Delete the numba caches in ``cache_dir`` (default: this package's ``__pycache__``) if the
    compiled sources changed since they were written; returns True if it deleted them.

    A read-only tree is left alone (numba then caches elsewhere and recompiles as it needs)."""
    cache_dir = _HERE / "__pycache__" if cache_dir is None else cache_dir
    digest = _digest()
    stamp = cache_dir / _STAMP
    try:
        if stamp.read_text() == digest:
            return False
    except OSError:
        pass
    try:
        cache_dir.mkdir(exist_ok=True)
        for f in list(cache_dir.glob("*.nbi")) + list(cache_dir.glob("*.nbc")):
            f.unlink(missing_ok=True)
        stamp.write_text(digest)
    except OSError as exc:
        log.debug("numba caches in %s left as they are: %s", cache_dir, exc)
        return False
    log.info("compiled sources changed: numba caches in %s dropped", cache_dir)
    return True


drop_stale()
