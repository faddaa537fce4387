"""The 1-D length tuning of the matching (fem.tuning) on closed-form frequency laws.

References: the exact root of f(L) = f0 (L0 / L)^p, and the lattice's promise that an error in
the frequencies within the eigensolver's tolerance (as a different thread count gives) cannot
move the tuned length.
"""

import numpy as np
import pytest

from rpud_common import ParameterError
from fem.tuning import find_length, snap, valid_bounds

F0, L0, P = 20_000.0, 0.05, 0.8          # Hz, m, exponent: a section that resonates lower when longer


def _law(noise=0.0, seed=0, trials=None):
    rng = np.random.default_rng(seed)

    def evaluate(v):
        if trials is not None:
            trials.append(v)                          # as find_length passes it
        v = snap(v)
        return F0 * (L0 / v) ** P * (1.0 + noise * rng.standard_normal())
    return evaluate


def test_finds_the_exact_root_to_xtol_and_brackets_on_lattice_lengths():
    trials = []
    target = 21_000.0
    exact = L0 * (F0 / target) ** (1 / P)
    got = find_length(_law(trials=trials), L0 + 3.3e-9, target, (0.025, 0.1), 1e-7, "horn.length", "the law")
    assert abs(got - exact) <= 1e-7 + 1e-8
    assert got == snap(got)
    # the start (off the lattice) and the bracketing steps are snapped; Brent's own points are not
    bracketing = trials[:3]
    assert all(t == snap(t) for t in bracketing) and bracketing[0] == snap(L0)
    assert len(trials) < 20


def test_a_start_a_fraction_of_a_cell_from_the_root_still_brackets():
    """The first step would be below 10 nm: it is widened to one lattice cell, not mistaken for
    the end of the bracket."""
    root = 0.05
    target = F0 * (L0 / root) ** P
    start = root - 2e-9                                          # 4e-8 relative: a sub-cell first step
    got = find_length(_law(), start, target * (1 - 1e-12), (0.025, 0.1), 1e-8, "horn.length", "the law")
    assert abs(got - root) <= 2e-8


def test_round_off_in_the_frequencies_does_not_move_the_tuned_length():
    """Noise of the size the frequencies are promised to: fem.modal solves omega^2 to tol = 1e-10
    relative, f to 5e-11, so two solves of one design (another thread count, another eigen
    path) may differ by up to 1e-10. Relative noise with sigma 1e-10 on every evaluation: 20
    noisy searches return the same length, bit for bit (the 10 nm lattice is 2e-7 of the length,
    1.6e-7 of f at p = 0.8: three orders above the noise)."""
    got = {find_length(_law(noise=1e-10, seed=s), L0, 20_300.0, (0.025, 0.1), 1e-5, "horn.length", "the law")
           for s in range(20)}
    assert len(got) == 1


class _Design:
    """A one-length design that is valid up to ``limit`` (m)."""

    def __init__(self, value, limit):
        self.value, self.limit = value, limit

    def get(self, path):
        return self.value

    def replace(self, changes):
        (v,) = changes.values()
        if not 0 < v <= self.limit:
            raise ParameterError("length", v, f"must be in (0, {self.limit}] m")
        return _Design(v, self.limit)


def test_bounds_shrink_to_valid_designs_on_the_lattice():
    d = _Design(0.05, limit=0.0712345678)
    lo, hi = valid_bounds(d, "length", (0.5, 2.0))
    assert lo == pytest.approx(0.025, abs=1e-8) and lo == snap(lo)
    assert 0.05 < hi <= d.limit and hi == snap(hi)
    d.replace({"length": hi})                                 # valid: no error


def test_a_target_outside_the_bracket_is_a_clear_error():
    message = r"outside the bracket: the law spans .* for horn.length in \[25.00, 100.00\] mm"
    with pytest.raises(ParameterError, match=message):
        find_length(_law(), L0, 40_000.0, (0.025, 0.1), 1e-5, "horn.length", "the law")


def test_match_settings_refuse_an_xtol_below_the_lattice():
    from fem.matching import MatchSettings

    with pytest.raises(ParameterError, match="xtol.*10 nm lattice"):
        MatchSettings(xtol=1e-9)




def test_a_trial_the_secant_puts_within_a_tenth_of_xtol_ends_the_search(monkeypatch):
    """Each evaluation is an eigen solve: a trial whose frequency error over the secant slope
    puts the root within RESIDUAL_FRACTION x xtol ends the search without Brent's last steps.
    Reference: the exact root of the power law, and the search with the stop switched off
    (Brent's method to xtol): the same lattice length within xtol of the root (the secant's
    distance estimate on this smooth law is good to a few % of the distance, inside the 10x
    margin), never more evaluations, and fewer over these targets."""
    import fem.tuning

    xtol, default = 1e-5, fem.tuning.RESIDUAL_FRACTION
    counts = {default: 0, 0.0: 0}
    for target in (19_000.0, 19_500.0, 19_900.0, 20_100.0, 20_500.0, 21_000.0):
        exact = L0 * (F0 / target) ** (1 / P)
        got = {}
        for fraction in (default, 0.0):
            monkeypatch.setattr(fem.tuning, "RESIDUAL_FRACTION", fraction)
            trials = []
            got[fraction] = find_length(_law(trials=trials), L0, target, (0.025, 0.1), xtol, "horn.length", "the law")
            counts[fraction] += len({snap(t) for t in trials})
            assert abs(got[fraction] - exact) <= xtol
        assert got[default] == got[0.0]
    assert counts[default] < counts[0.0], counts
