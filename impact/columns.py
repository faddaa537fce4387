"""Codes and column layouts shared by the engines and their results (plain integers).

* segment modes: :data:`FREE` (free flight), :data:`ON_HORN` / :data:`ON_TOOL` (the free mass
  sticks to the horn / the tool);
* event kinds :data:`KIND_HORN`, :data:`KIND_TOOL` and sticking bodies :data:`BODY_HORN`,
  :data:`BODY_TOOL` (int8 in the compiled engines' arrays);
* run status :data:`STATUS_OK`, :data:`STATUS_PINCHED`, :data:`STATUS_MAX_EVENTS`,
  :data:`STATUS_CONTACT` (a compliant contact not resolved);
* window statistics columns ``S_*`` (:data:`N_STATS` of them; :func:`impact.result.window_stats`
  and :func:`impact.kernel.ensemble_stats`), followed in the coupled model by ``C_*``
  (:data:`N_CSTATS` in all; :func:`impact.kernel_modal.ensemble_coupled`).
"""

FREE, ON_HORN, ON_TOOL = 0, 1, 2
KIND_HORN, KIND_TOOL = 0, 1
BODY_HORN, BODY_TOOL = 0, 1
STATUS_OK, STATUS_PINCHED, STATUS_MAX_EVENTS = 0, 1, 2
#: status of a run whose compliant contact was not resolved in 1e6 integration steps
STATUS_CONTACT = 4

#: window statistics: impact counts, tool kinetic energy after impact and its gain (J), horn work
#: (J), sticking time on horn and tool (s), run status, events of the whole run
S_N_TOOL, S_N_HORN, S_KE_AFTER, S_KE_GAIN, S_HORN_WORK, S_T_ON_HORN, S_T_ON_TOOL, S_STATUS, \
    S_N_EVENTS = range(9)
N_STATS = 9
#: coupled model: drive work on the modes and the residual (J), modal damping loss (J), the
#: fundamental ``int u e^{-jWt} dt`` (m s), electrical energy drawn (J), source loss (J)
C_DRIVE, C_DAMP, C_FUND_RE, C_FUND_IM, C_ELEC, C_SOURCE_LOSS = range(N_STATS, N_STATS + 6)
N_CSTATS = N_STATS + 6
