"""Adaptive mesh refinement for the pseudospectral back end (``method: {mesh: {...}}``).

Each mesh iteration solves the NLP on the current mesh (warm-started from the previous
iteration's solution), estimates the error of every segment, and refines the segments whose
error is above the tolerance, until every segment is within it or ``max_iterations`` is
reached.

Error estimate (does not trust the collocation equations)
    In segment k, the state interpolant X(t) of the collocated solution is compared with the
    state obtained by *integrating* the dynamics from X(t_{k-1}) with the collocated control
    (the segment's control interpolant, clipped to the control bounds so that it stays
    admissible), by an adaptive Dormand-Prince 8(5,3) integrator (SciPy's DOP853, tolerances
    far below the mesh tolerance), on a finer set of points in the segment (N_k + 6
    Legendre-Gauss-Lobatto points). The relative error is that of Patterson, Hager & Rao,
    "A ph mesh refinement method for optimal control", Optimal Control Appl. Methods 36 (2015)
    398-421, eq. (29)-(30):

        e_k = max_i max_l |Xhat_i(t_l) - X_i(t_l)| / (1 + max_j |X_i(t_j)|)

    where Liu, Hager & Rao, "Adaptive mesh refinement method for optimal control using
    nonsmoothness detection and mesh size reduction", J. Franklin Inst. 352 (2015) 4081-4106,
    also integrate the dynamics with the collocated control (their estimate uses an ODE
    integration of the dynamics instead of a higher-degree collocation). In addition, the
    violation of the state bounds and path constraints by the integrated trajectory on the
    same points, relative to 1 + |bound|, counts as error (a polynomial state may leave a
    bound between collocation points), and so does each integral's quadrature on the segment
    against its integral along the integrated trajectory (relative to 1 + max |integral|).
    Over the problem, the boundary conditions, links and integral constraints are evaluated
    with every phase flown from x(t0) (``estimate.phase_end``, ``terminal.terminal_error``):
    their violation counts as the mesh's error, and while it is above tolerance the segments
    are held to tolerance * (largest segment error / terminal error) (docs/mesh.md).

Refinement rule
    - Smooth segment (no change of active set inside it): raise the degree by
      P_k = ceil(log(e_k / tol) / log(N_k)) (Patterson, Hager & Rao 2015, eq. (32)); when
      N_k + P_k exceeds ``max_degree``, split the segment into
      B_k = max(ceil((N_k + P_k) / min_degree), 2) equal segments of degree ``min_degree``
      (their eq. (34)).
    - Nonsmooth segment (an active-set change inside it: a control leaving or reaching a
      bound, or a state bound / path constraint becoming active or inactive, between two
      consecutive collocation points -- the switches and constraint corners of the solution,
      in the spirit of Liu, Hager & Rao's nonsmoothness detection): split it at the two
      collocation points that bracket each change and cut the bracket into ``bracket_pieces``
      equal pieces, all of degree ``min_degree``. The segment that holds the switch thus
      shrinks by a factor of about 2 * bracket_pieces / N_k per iteration, and the
      segments on either side of it are smooth, so the switch ends up on (or within a tiny
      segment next to) a segment boundary. Used when the switch cannot be located:
    - Located switches and corners (``locate_features``): a bound-to-bound switch from the
      quadrature of the collocated control (``locate_switches``), a corner from the crossing
      of the neighbouring smooth segments' control polynomials (``_corner``), another jump
      from the same quadrature with those polynomials in place of the bounds (``_jump``).
      Each one farther than ``corner_tolerance`` from a breakpoint becomes one: the nearest
      breakpoint is moved onto it when within ``snap`` of the segment width, else the segment
      is split there; the mesh is not converged while one is off its breakpoint.
    - Ends of state-constrained arcs (``locate_junctions``, our method): from the boundary
      control u_b (the bounded state differentiated along the dynamics until a control
      appears, ``boundary_controls``), the zero of u_U - u_b with u_U the control polynomial
      of the nearest unconstrained segment (first-order constraints with a control jump: the
      zero of that segment's state polynomial minus the bound); repeated on the same mesh
      shape, a secant step on the map breakpoint -> estimate.
    - On an arc mesh (every interior breakpoint on a located feature), breakpoints are moved
      onto their re-located features and the segments next to them kept (``_arc_mesh_moves``).
    - At most ``growth`` times the segments per refinement (largest errors first); a split
      over the remaining budget is cut down to it (``_within_budget``), never dropped.
    - Never the same mesh twice while the tolerance is unmet: if the rules leave a phase's
      mesh unchanged, its worst segment gets degree + 1 (up to ``max_degree``) or is bisected
      (``_forced_refinement``); when that is impossible ``MeshStalled`` ends the run with
      ``mesh_not_converged`` and the reason in the message.
    - Coarsening (``coarsen``), once a mesh meets the tolerance: Liu, Hager & Rao (2015)
      reduce degrees and merge segments where the error is far below tolerance; here
      consecutive segments are merged and every segment gets the smallest degree for which
      one Legendre polynomial fits the solution's states over it within
      ``coarsen_margin * tolerance``. The coarse mesh is solved and estimated like any other
      (refined again if it misses); the smallest mesh that met the tolerance is returned.
      A second candidate is the arc mesh: one segment per arc between located features, a
      state-constrained arc fitted on its boundary-control trajectory (``_arc_mesh``).
    - Controls at phase junctions (``junction_control: limit``, the default;
      ``limit_junction_controls``): a control collocated at a phase's end point where another
      phase joins (LGR: tau = +1, LGR-start: tau = -1, LGL: both), and for LGL both controls at
      a breakpoint on a located switch/corner, are constrained to the one-sided limit of their
      segment's interior control polynomial. The continuous problem leaves the control at that
      instant free (measure zero); the NLP weights it by its quadrature weight and, left free,
      set it to the other bound so that the control polynomial overshoots its bound between
      the nodes (two-phase double integrator: estimate stuck at 2.8e-6 after 8 iterations).
    - Optional regularisation (``regularise`` > 0): w * int (du/ds)^2 ds over the arcs where
      the control chattered (``chattering_segments``, ``regularise``); the reported objective
      leaves the term out. It changes the problem (measured bias in docs/mesh-refinement.md).

Switches on or near breakpoints (``switches.solve_switch_times``): the breakpoints are NLP
unknowns in one more solve, the bang controls of their segments held, at every mesh in
free-time phases and on a mesh within tolerance in fixed-time ones; the converged mesh is
solved that way once more for PMP's costates (``with_switch_costates``).
Symbolic steps (``budget.bounded``): in a forked child with a time and memory bound, skipped
with a note past it; ``symbolic: false`` turns them off.

Warm start (``warm_start``): with ``multipliers`` (default) the new mesh starts from the
previous mesh's polynomials and from its multipliers mapped through the costate, the path and
bound multiplier densities and by name (``solve/warm_start.py``), solved by cyipopt directly
(``ipopt.solve(..., multipliers=...)``; Pyomo's cyipopt solver passes no ``lagrange``/``zl``/
``zu``); with ``primal`` only the states and controls, sampled from the polynomials and
interpolated onto the new mesh (``transcribe.guess``).
"""
__all__ = ["solve_adaptive"]


def __getattr__(name: str):
    # lazy: a single solve imports mesh.segments (solve/arcs.py) without the whole refinement
    # (drive and its locators, estimate, verify: 20 ms of a small run's start-up)
    if name == "solve_adaptive":
        from .drive import solve_adaptive

        return solve_adaptive
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
