"""A refined mesh that does not solve from the mesh before: solved once more from the file's
guess, as the first mesh started (a poor solution warm-starts a poor solve; unseen8: a
pendulum's third mesh ended infeasible after two multi-swing solutions).

A warm-started solve is capped at a few times the first mesh's cold solve (``warm_cap``): the
hanging chain's meshes 1-4 were spurious zigzags (J 4.79-4.95 against 5.068), and mesh 5 took
2,516 Ipopt iterations (2.3 s of a 3.5 s run) to leave the last one's warm start; from the
file's guess it took 89. Within that, the start from the mesh before's multipliers may take a few
times the mesh before's iterations (``multiplier_cap``) before the same point is solved without
them: the reorientation's fourth mesh (unseen48 F2), its third solved in 14, ran with them to
5,100 iterations (32 s of a 75 s run), and without them solved in 281. Where neither start
solves within the cap, the warm start runs again without it, as before the cap. A mesh whose
zigzag exploits an integral's quadrature is no warm start at all (``exploits_quadrature``).

A first mesh that cannot solve for want of nodes (infeasible where the problem is not, or no
freedom left by many end values) is bisected before the run gives up (``bisect_first``)."""
from __future__ import annotations

from typing import Callable

from .outcome import GOOD

#: a refined mesh's warm-started solve may take this many times the first mesh's iterations
#: (at least WARM_CAP_MIN) before the file's guess is tried
WARM_CAP_FACTOR, WARM_CAP_MIN = 4, 200


def warm_cap(options: dict, first_iterations: int | None) -> int | None:
    """The max_iter of a refined mesh's warm-started solve; None to leave the file's: no first
    solve to measure by, or the file's own max_iter at or below the cap."""
    if first_iterations is None:
        return None
    cap = max(WARM_CAP_MIN, WARM_CAP_FACTOR * int(first_iterations))
    given = options.get("max_iter")
    return None if given is not None and int(given) <= cap else cap


def multiplier_cap(last_iterations: int | None) -> int | None:
    """The max_iter of a warm start with the mesh before's multipliers (``last_iterations``
    its solve's); None before there is one."""
    return None if last_iterations is None else max(WARM_CAP_MIN, WARM_CAP_FACTOR * int(last_iterations))


def restart(it: int, info, capped: int | None, *, cold: Callable, warm: Callable, solve: Callable, timer):
    """``info``: the failed solve of mesh ``it`` (``capped``: its max_iter when warm_cap set it).
    ``cold()`` builds the model from the file's guess, ``warm()`` (model, multipliers) from the
    mesh before, ``solve(model, multipliers, label)`` solves one. Returns (model, SolveInfo,
    multipliers) to replace the failed solve, or None to keep it."""
    with timer.measure("build"):
        model = cold()
    with timer.measure("solve"):
        retry = solve(model, None, f"[mesh {it}, from the guess]")
    if retry.status in GOOD:
        cut = f", the {capped} a warm start may take" if capped is not None and info.status == "max_iter" else ""
        retry.message += (f" (from the file's guess: from the mesh before, Ipopt ended '{info.status}' after "
                          f"{info.iterations} iterations{cut})")
        retry.iterations += info.iterations
        return model, retry, None
    if capped is None or info.status != "max_iter":
        return None
    with timer.measure("build"):
        model, multipliers = warm()
    with timer.measure("solve"):
        again = solve(model, multipliers, f"[mesh {it}, warm, uncapped]")
    again.iterations += info.iterations + retry.iterations
    return model, again, multipliers


def bisect_first(solve: Callable, tr, info, meshes: dict, what: str, failing: Callable, times: int,
                 notes: list):
    """The first mesh bisected up to ``times`` times while ``failing(info)``; ``solve(meshes,
    bisections)`` -> (transcription, info). The first bisection that solves replaces it, with
    a note; otherwise the message says how far it went and the first solve stands."""
    size = (f"{next(iter(meshes.values())).segments} segments" if len(meshes) == 1 else
            ", ".join(f"{k}: {m.segments} segments" for k, m in meshes.items()))
    trial = meshes
    for bisections in range(1, times + 1):
        trial = {k: m.bisected() for k, m in trial.items()}
        t_fine, retry = solve(trial, bisections)
        retry.iterations += info.iterations
        if retry.status in GOOD and not failing(retry):
            notes.append(f"the first mesh ({size}) {what}: bisected {bisections} time(s), it "
                         "solved (a finer start mesh avoids the detour)")
            return t_fine, retry, trial
        if not failing(retry):
            break
    info.message += f"; the first mesh ({size}) bisected {bisections} time(s) too (times {2 ** bisections}): no better"
    return tr, info, meshes


def exploits_quadrature(tr, term, worst, max_err: float) -> bool:
    """Some control zigzags from node to node and the largest error is an integral's: its
    quadrature against its flight (a segment's), or a condition on it flown from x(t0)."""
    from .segments import solution_arrays, zigzag

    on_integral = (term.error >= max_err and "integral(" in term.where) or (
        worst is not None and worst.error >= max_err and str(worst.state).startswith("integral("))
    if not on_integral:
        return False
    for pb in tr.phases:
        U = solution_arrays(pb)[1]
        if any(zigzag(U[:, j]) for j in range(U.shape[1])):
            return True
    return False
