"""The Examples sections of the public entry points run: each listed module's doctests pass and
there is at least one (an example that stopped running would otherwise rot unseen)."""

import doctest
import importlib

import pytest

MODULES = ["rpud_common.errors", "rpud_common.records", "geometry", "geometry.design", "fem.forms",
           "fem.assembly", "fem.modal", "fem.harmonic", "impact.model", "impact.stats", "impact.sweeps"]


@pytest.mark.parametrize("name", MODULES)
def test_examples_run(name):
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE,
                             raise_on_error=False, verbose=False)
    assert result.attempted > 0, f"{name} has no example"
    assert result.failed == 0
