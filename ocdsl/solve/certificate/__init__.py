"""Optimality certificate of a collocated solution, from arrays and the symbolic model.

Given a :class:`~ocdsl.symbolic.model.Model`, numeric parameter values, the nodes of a
solution (time, states, controls and costate estimates at the collocation nodes; a
:class:`~ocdsl.result.PhaseTrajectory` or a mapping with the same fields), the control
bounds, the Lagrange integrand ``L`` and the objective kind, :func:`certificate` checks
Pontryagin's necessary conditions (the re-integration is the verification's, ocdsl/verify). No Pyomo: any back end
that estimates costates can be certified.

Conventions (the minimisation form of the problem; maximise ``J`` by minimising ``-J``):

* ``H = L + lambda^T f`` (the Gauss-pseudospectral costate convention, Benson et al.);
* along an optimal trajectory ``dH/dt = dH/dt|explicit``; with no explicit time
  dependence ``H`` is constant, and with a free final time ``H(tf) = -dPhi/dtf``:
  ``-1`` for ``minimize tf`` (``objective="min_tf"``), ``+1`` for ``maximize tf``
  (``"max_tf"``), ``0`` for a free final time whose Mayer term does not depend on ``tf``
  (``"free_tf"``); for a fixed final time (``"fixed_tf"``) only constancy is checked;
* PMP minimises ``H`` over the admissible controls: on interior arcs ``dH/du = 0``; at an
  upper bound ``dH/du < 0`` and at a lower bound ``dH/du > 0`` (``dH/du`` is the switching
  function).
* path constraints ``lo_k <= g_k(x, u, t) <= hi_k`` with multipliers ``mu_k(t)`` (given,
  e.g. from the NLP duals, ``ocdsl.solve.costates.path_multipliers``) enter the augmented
  Hamiltonian ``H_aug = L + lambda^T f + sum_k mu_k (g_k - b_k)`` (b_k the active bound):
  stationarity and the switching functions use ``dH_aug/du = dH/du + sum_k mu_k dg_k/du``;
  the Hamiltonian check uses ``H``, since ``mu_k (g_k - b_k) = 0`` by complementarity
  (measured apart); ``mu_k >= 0`` where ``g_k`` is at its upper bound, ``<= 0`` at its
  lower bound, free for an equality (the sign of ``mu_k`` selects b_k: an upper-only
  constraint with ``mu_k < 0`` has no bound to be active at).

Checks and their measured numbers (see :func:`certificate` for the dict):

* ``hamiltonian``: mean, min, max, the deviation from the expected value (or from the
  mean for a fixed final time), relative to ``|expected|`` (or, when the expected value is
  0, to the mean size of the terms ``|L| + sum |lambda_i f_i|``);
* ``stationarity``: ``max |dH/du|`` at nodes off the bounds, relative to the size of its
  terms ``|dL/du| + sum |lambda_i df_i/du|`` (maximum over the nodes);
* rounding: a node's ``|dH/du|`` times its share of time, and ``|H - reference|`` times
  the duration, below ``Tolerances.rounding`` (1e-12, in the NLP's units: objective per
  node) are zero; without that floor a zero optimum (lambda = 0, L = 0) compared rounding
  with rounding;
* ``switching``: the fraction of saturated nodes (within ``saturation`` x range of a bound)
  whose switching-function sign agrees with the active bound (a node near a bound whose
  ``dH/du`` vanishes to the stationarity tolerance is weakly active and agrees; counted
  apart as ``weakly_active_nodes``; so does a node next to a change of bound whose
  ``|dH/du|`` is small against the control's largest, ``Tolerances.switch_node``: the switch);
* a Hamiltonian check that fails while every control is bang-bang, every switching sign
  agrees and the mean of H is right (only its spread fails) is ``inconclusive``
  (``passed`` None, the reason under ``inconclusive``), never failed: no node is
  stationary, so the NLP's costates are unique only up to a shift of the switching
  functions the bound multipliers absorb, and H moves with it;
* ``bang_bang``: per bounded control, the fraction of nodes at a bound, the switch count,
  the switch times (zero crossings of the linearly interpolated switching function between
  saturated nodes on opposite bounds) and the sequence of bounds; descriptive, no pass/fail;
* ``path_multipliers`` (only with path constraints): per constraint the complementarity
  ``max |mu_k (g_k - b_k)|`` (b_k the bound the sign of mu_k points to; for an equality
  its value), relative to the Hamiltonian's term scale, and the sign condition: a
  multiplier of the wrong sign (no finite bound on that side) is measured as
  ``|mu_k| G_k`` relative to the same scale, G_k the size of g_k (its range over the nodes
  or its largest finite bound, at least 1e-12). Passes when both stay below
  ``Tolerances.complementarity`` and ``Tolerances.stationarity`` respectively.
"""
from __future__ import annotations

from .checks import certificate
from .conditions import SymbolicConditions, symbolic_conditions
from .nodes import hamiltonian_arrays
from .tolerances import EXPECTED_H, OBJECTIVE_KINDS, Tolerances

__all__ = ["OBJECTIVE_KINDS", "EXPECTED_H", "Tolerances", "SymbolicConditions", "symbolic_conditions",
           "hamiltonian_arrays", "certificate"]
