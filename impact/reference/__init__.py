"""The readable reference engines: the tests' second methods for the compiled ones.

* :mod:`impact.reference.ivp`: the impact model integrated by scipy's ``solve_ivp`` with terminal
  contact events (:func:`simulate_ivp`), sharing nothing with the event engines but the
  parameters;
* :mod:`impact.reference.events`: :class:`EventEngine`, the kinematic horn's event loop in plain
  Python (``impact.model.simulate(engine="python")``);
* :mod:`impact.reference.modal`: :class:`ModalEngine`, the modal horn's event loop
  (``impact.coupled.simulate_coupled(engine="python")``);
* :mod:`impact.reference.search`: their event search (grid bracketing, bisection, Brent).

Loaded on first use, so importing this package stays light.
"""

from rpud_common.lazy import exports

_WHERE = {"simulate_ivp": "ivp", "EventEngine": "events", "ModalEngine": "modal"}
__all__ = list(_WHERE)
__getattr__, __dir__ = exports(__name__, _WHERE)
