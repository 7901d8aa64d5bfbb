"""Matplotlib figures of a run folder (Agg only, no pyplot state).

Every ``fig_*`` function takes what it draws (a :class:`~ocdsl.result.Result`, tables)
and returns a list of :class:`Fig` (possibly empty when the run folder has nothing to
draw); none of them raises for a missing optional piece. :func:`to_svg` and
:func:`to_pdf` turn a figure into vector bytes. One module per figure kind: time
histories (:mod:`.trajectory`), Hamiltonian and switching functions
(:mod:`.hamiltonian`), paths in space (:mod:`.positions`) and in a declared frame
(:mod:`.frame`), mesh refinement
(:mod:`.mesh`), controllers (:mod:`.closed_loop`), Pareto fronts (:mod:`.pareto`),
studies (:mod:`.study`) and solver convergence (:mod:`.solver`); shared parts in
:mod:`.base` and :mod:`.time`.
"""
from __future__ import annotations

from ocdsl.report.figures.base import HAMILTONIAN_KEYS, Fig, tex_name, to_pdf, to_svg
from ocdsl.report.figures.closed_loop import closed_loop_tables, fig_closed_loop
from ocdsl.report.figures.frame import fig_frame
from ocdsl.report.figures.hamiltonian import fig_hamiltonian
from ocdsl.report.figures.mesh import fig_mesh_history
from ocdsl.report.figures.pareto import fig_pareto
from ocdsl.report.figures.positions import fig_positions
from ocdsl.report.figures.solver import fig_solver_history
from ocdsl.report.figures.study import fig_compare_runs, fig_histograms, fig_sweep
from ocdsl.report.figures.trajectory import fig_costates, fig_other_extra, fig_reintegration, fig_states_controls

__all__ = ["Fig", "HAMILTONIAN_KEYS", "closed_loop_tables", "fig_closed_loop", "fig_compare_runs", "fig_costates",
           "fig_frame", "fig_hamiltonian", "fig_histograms", "fig_mesh_history", "fig_other_extra", "fig_pareto",
           "fig_positions", "fig_reintegration", "fig_sweep", "fig_solver_history", "fig_states_controls",
           "tex_name", "to_pdf", "to_svg"]
