"""Shared test configuration: the slow tier and the verification-manual recorder.

Slow tests
    ``make test-fast`` runs ``pytest -m "not slow"``. The tests listed in ``SLOW`` below were
    measured (``pytest -n 2 --dist loadfile --durations=0``) to take seconds each; they are marked
    ``slow`` here rather than by decorators so the list is in one place and is re-measured as one.
    Every test still runs in the full ``make test``.

Verification records
    Tests marked ``vv`` take the ``vv`` fixture and call ``vv.record(...)`` with the reference
    value and the value they computed. Each call writes one JSON file to ``docs/_generated/vv/``
    (``RPUD_VV_DIR`` overrides the folder); the documentation's Verification manual renders one
    page per file. One file per check, named by the check, so parallel xdist workers never write
    the same file.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
VV_DIR = Path(os.environ.get("RPUD_VV_DIR", ROOT / "docs" / "_generated" / "vv"))

# Measured slow (a test id prefix: a file, or a file::test). Re-measure with --durations=0.
SLOW: tuple[str, ...] = ()


def pytest_collection_modifyitems(config, items):
    """Mark every test whose node id starts with an entry of SLOW as ``slow``, and every test that
    takes the ``vv`` fixture as ``vv`` (so ``pytest -m vv`` regenerates the V&V records)."""
    for item in items:
        if "vv" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.vv)
        nodeid = item.nodeid.replace("\\", "/")
        if any(nodeid == s or nodeid.startswith(s + "::") or nodeid.startswith(s + "[") for s in SLOW):
            item.add_marker(pytest.mark.slow)


class VVRecorder:
    """Writes verification records: one JSON per check, read by the docs' V&V manual.

    Parameters
    ----------
    folder : pathlib.Path
        Where the records go.
    nodeid : str
        The pytest id of the test that records (printed on the check's page).
    """

    def __init__(self, folder: Path, nodeid: str):
        self.folder = folder
        self.nodeid = nodeid

    def record(self, check_id: str, *, title: str, description: str, reference: str, assumptions: str,
               target: float, computed: float, tolerance: float, unit: str = "",
               tolerance_kind: str = "relative", quantity: str = "") -> dict:
        """Record one check and return its record.

        Parameters
        ----------
        check_id : str
            Short stable identifier, e.g. ``"VV-AX-01"`` (the file name and the page's name).
        title, description, reference, assumptions : str
            The ANSYS Verification Manual sections (Markdown allowed).
        target : float
            The reference value, in ``unit``.
        computed : float
            The toolkit's value, in ``unit``.
        tolerance : float
            The test's acceptance: relative (``|computed/target - 1|``) or absolute
            (``|computed - target|``, in ``unit``), per ``tolerance_kind``.
        unit : str
            Unit of target and computed (empty for dimensionless).
        tolerance_kind : {"relative", "absolute"}
            How ``tolerance`` is applied.
        quantity : str
            What the number is (e.g. "first thickness resonance").

        Returns
        -------
        dict
            The record written, with ``ratio`` (computed/target, None for a zero target) and
            ``passed`` (the test's own criterion).
        """
        if tolerance_kind not in ("relative", "absolute"):
            raise ValueError(f"tolerance_kind must be 'relative' or 'absolute', got {tolerance_kind!r}")
        target, computed = float(target), float(computed)
        ratio = computed / target if target != 0 else None
        if tolerance_kind == "relative":
            deviation = abs(computed / target - 1.0) if target != 0 else math.inf
        else:
            deviation = abs(computed - target)
        rec = {
            "id": check_id, "title": title, "quantity": quantity, "description": description,
            "reference": reference, "assumptions": assumptions, "unit": unit,
            "target": target, "computed": computed, "ratio": ratio,
            "tolerance": float(tolerance), "tolerance_kind": tolerance_kind,
            "deviation": deviation, "passed": bool(deviation <= tolerance), "test": self.nodeid,
        }
        self.folder.mkdir(parents=True, exist_ok=True)
        tmp = self.folder / f".{check_id}.{os.getpid()}.tmp"
        tmp.write_text(json.dumps(rec, indent=1) + "\n")
        os.replace(tmp, self.folder / f"{check_id}.json")    # atomic: a reader never sees half a file
        return rec


@pytest.fixture
def vv(request) -> VVRecorder:
    """The verification recorder of the requesting test (see ``VVRecorder.record``)."""
    return VVRecorder(VV_DIR, request.node.nodeid)
