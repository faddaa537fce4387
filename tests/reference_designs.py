"""The drill the tests' pinned reference constants belong to (no tests here).

Several tests compare with constants computed once at a cost the suite cannot pay again: the
converged (r, z) answers of tests/axisym_reference.py for the default drill without slots and
teeth (f_r 19 682.31 Hz, f_a 21 410.33 Hz, the tip amplitude per volt, torsion and bending), the
coupler refinement study, the teeth-motion refinement study and the sector-size calibration of
the resource guard. Those constants hold for one drill, the article's (Table 1: no bolt part,
:func:`geometry.examples.article_design`), at one horn length and one coupler length, which this
module fixes, so the tests stay valid whatever the default design carries: a test that compares
with such a constant builds its design from :func:`reference_default`.
"""

from __future__ import annotations

from geometry.examples import article_design

REFERENCE_LENGTHS = {"horn.length": 0.0671, "coupler.length": 0.0499}
"""Horn and coupler lengths (m) of the drill the pinned reference constants were computed for."""


def reference_default():
    """The article's drill (its parts, materials, fillets) at :data:`REFERENCE_LENGTHS`."""
    return article_design().replace(REFERENCE_LENGTHS)
