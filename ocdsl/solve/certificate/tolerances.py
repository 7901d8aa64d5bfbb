"""The certificate's objective kinds, expected Hamiltonian values and pass/fail thresholds."""
from __future__ import annotations

from dataclasses import dataclass

from ...verify.checks import RESOLUTION

OBJECTIVE_KINDS = ("min_tf", "max_tf", "free_tf", "fixed_tf")
EXPECTED_H = {"min_tf": -1.0, "max_tf": 1.0, "free_tf": 0.0, "fixed_tf": None}

@dataclass(frozen=True)
class Tolerances:
    """Pass/fail thresholds of :func:`certificate` (all relative, see the module doc)."""

    hamiltonian_mean: float = 2e-3   # |mean(H) - expected| / scale
    hamiltonian_max: float = 3e-2    # max |H - expected| / scale
    stationarity: float = 1e-2       # max |dH/du| / term size on interior nodes
    complementarity: float = 1e-3    # max |mu_k (g_k - b_k)| / Hamiltonian term scale
    sign_agreement: float = 0.99     # fraction of saturated nodes
    # a saturated node next to a change of bound whose |dH/du| is at most this share of the
    # control's largest: the switch itself, where the switching function is 0 and the NLP's
    # costate estimate gives either sign (unseen5: LGL, a breakpoint on the switch, +0.048
    # against a largest 2.28, the only disagreeing node of 40 failed the run)
    switch_node: float = 0.05
    saturation: float = 0.01         # "at a bound": within this fraction of the bound range
    bang_bang: float = 0.95          # fraction of nodes at a bound to call a control bang-bang
    # rounding, in the NLP's own units (objective per node: |dH/du| times the node's share of
    # time, |H - reference| times the duration): a residual below it is zero, whatever the
    # relative test says. Ipopt solves to 1e-8 in these units, so a residual 1e4 below that
    # is not one the solver resolved; a zero optimum (exact tracking: lambda = 0, L = 0)
    # otherwise compared rounding to rounding (relative 1.0, "failed")
    rounding: float = 1e-12
    # what the NLP resolves, in the same units: ten times Ipopt's tol (ocdsl's default 1e-8),
    # which bounds its *scaled* dual infeasibility (Ipopt divides by s_d >= 1). A Hamiltonian
    # whose terms over the whole duration stay below it is made of costates the solver never
    # resolved (a zero-residual fit, J* = 0: every term 1e-10, H "off" by 3.4 times its scale
    # with J right to 3e-11; zero costates at the optimum, unseen27: x' = u, min (x(1) -
    # 0.5)^2, and a phase cost that balances the final value, H of 2.2e-8 "failed" at 0.45 of
    # itself with J right to 6e-16 and 4.8e-10): it is not judged, neither passed nor failed
    resolution: float = RESOLUTION
