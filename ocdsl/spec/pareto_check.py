"""The sections of a Pareto file outside ``pareto:`` go through the same compile path as a
problem file, so that ``check`` and ``run`` refuse what a problem file would refuse.

A ``solver: nlp`` file is a problem file with a ``pareto:`` block: it is compiled whole. A
``solver: closed_form`` file describes its phases as ``{duration: [lo, hi], fix: {u: v}}``
and its boundary conditions under ``problem: constraints:`` with ``phase.x(t0)``; it is
compiled as the multi-phase problem it stands for (each phase from 0 to a free tf within
its duration, the fixed controls as equalities, the constraints as links, objective the sum
of the Pareto objectives with ``phase.duration`` read as ``phase.tf``), every error at the
line of the file where its text was written.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from .errors import SpecError
from .loader import Located

_CLOSED_FORM_KEYS = {"name", "description", "definitions", "model", "parameters", "phases", "problem",
                     "alternatives", "pareto", "expect"}


#: what a Pareto set's ``expect`` checks: the set, not a point
SET_CHECKS = ("n_solutions", "pareto_labels")


def _set_checks(located: Located, solver: str) -> None:
    """A Pareto set's ``expect`` names the set's checks only; a check it would not run is
    refused (unseen54 F1/F2: `objective: 99` under a top-level `expect:` of a solver: nlp file,
    or under `pareto: expect:`, was read and never checked: exit 0, `ok: true`)."""
    doc = located.data
    inner = (doc.get("pareto") or {}).get("expect") if isinstance(doc.get("pareto"), dict) else None
    if solver != "closed_form" and isinstance(doc.get("expect"), dict) and doc["expect"]:
        first = next(iter(doc["expect"]))
        raise SpecError([located.issue(("expect", first), f"a top-level `expect:` is not checked on a Pareto set "
                                       f"(its points differ in every value); the set's own checks go under "
                                       f"`pareto: expect:` ({', '.join(SET_CHECKS)}); each point's values are in "
                                       f"points/<label>/result.json")])
    where = [("pareto", "expect", inner)] if isinstance(inner, dict) else []
    if solver == "closed_form" and isinstance(doc.get("expect"), dict):
        where.append(("expect", None, doc["expect"]))
    for *path, checks in where:
        unknown = [k for k in checks if k not in SET_CHECKS]
        if unknown:
            loc = tuple(p for p in path if p is not None) + (unknown[0],)
            raise SpecError([located.issue(loc, f"unknown check '{unknown[0]}' in a Pareto set's expect: it "
                                           f"checks {' and '.join(SET_CHECKS)}")])


def check_sections(path: str | Path, located: Located, solver: str, method: str | None = None) -> None:
    """Compile the model and problem sections of a Pareto file; a SpecError lists every issue.
    What the NLP solver cannot run is refused here too (unseen12 F5: both ended in a traceback
    after `check` said ok)."""
    from .compile import _Compiler, validate

    _set_checks(located, solver)
    if solver != "closed_form":
        if method == "weighted":
            raise SpecError([located.issue(("pareto", "method"), "method weighted runs with solver: closed_form "
                                           "only; with solver: nlp use method epsilon (the epsilon-constraint "
                                           "method traces the same front, its non-convex parts included)")])
        loaded = _Compiler(Path(path), located, validate(located), {}).compile()
        transcription = getattr(loaded.method, "transcription", None)
        if transcription not in ("LG", "LGR", "LGR-start", "LGL"):
            # unseen22: a flat-bspline file ended in AttributeError ('segments') after `check` said ok
            raise SpecError([located.issue(("method", "transcription"), f"solver: nlp solves every Pareto point by "
                                           f"pseudospectral collocation (LG, LGR, LGR-start or LGL); "
                                           f"`transcription: {transcription}` is not one: run its points with "
                                           f"`ocdsl study`, or use a pseudospectral method here")])
        if getattr(loaded.method, "mesh", None) is not None:
            # every point is solved on the file's uniform mesh (unseen19 q5: `mesh:` ignored in
            # silence, three of four points unverified, the message then advising `mesh:`)
            raise SpecError([located.issue(("method", "mesh"), "solver: nlp solves every Pareto point on the "
                                           "file's uniform mesh (segments x degree); `mesh:` is not applied to "
                                           "the points: remove it and choose segments that resolve them, or run "
                                           "single points with `ocdsl run` and `mesh:`")])
        if method == "epsilon":
            _epsilon_parameter(located, loaded)
            _epsilon_objectives(located, loaded)
        if method == "enumerate":
            free = [f"{ph.name}.{c}" if len(loaded.problem.phases) > 1 else str(c)
                    for ph in loaded.problem.phases for c in ph.controls if len(set(ph.bounds_of(c)[:2])) != 1]
            if free:
                raise SpecError([located.issue(("pareto", "method"), f"method enumerate with solver: nlp needs every "
                                               f"control fixed (e.g. `{free[0].split('.')[-1]} == 1`); free: "
                                               f"{', '.join(free)}. For a free control use method epsilon")])
        return
    doc = located.data
    # what `run` refuses, refused here at its line (unseen35 F6: `check` said ok for a weighted
    # closed-form file that `run` refused without a line)
    if method != "enumerate":
        raise SpecError([located.issue(("pareto", "method"), f"solver: closed_form runs method enumerate only "
                                       f"(the two-burn programme's roots); method {method} from a file: use "
                                       f"solver: nlp with method epsilon (weighted sums are the Python API's, "
                                       f"ocdsl.study.pareto.weighted with your own solve_point)")])
    unknown = [k for k in doc if k not in _CLOSED_FORM_KEYS]
    if unknown:
        raise SpecError([located.issue((unknown[0],), f"unknown key '{unknown[0]}' in a closed-form Pareto file")])
    stand_in, lines = _stand_in(doc, located)
    synthetic = Located(located.file, stand_in, lines, located._text)
    _Compiler(Path(path), synthetic, validate(synthetic), {}).compile()
    # a model that compiles but is not the two-burn programme's (after the compile's own errors)
    use = (doc.get("model") or {}).get("use") if isinstance(doc.get("model"), dict) else None
    if use != "relative_motion_secular":
        raise SpecError([located.issue(("model",), "solver: closed_form exists for the two-burn programme of "
                                       "`model: {use: relative_motion_secular}` only; for another model use "
                                       "solver: nlp")])


def _epsilon_parameter(located: Located, loaded) -> None:
    """solver nlp's epsilon method sets each bound through a parameter of the file (`tf <= eps`):
    without one, `check` said ok and `run` refused with no line (unseen35 P44)."""
    eps = (located.data.get("pareto") or {}).get("epsilon") or {}
    name = eps.get("parameter") if isinstance(eps, dict) else None
    known = sorted(str(k) for k in loaded.parameters)
    if not name:
        raise SpecError([located.issue(("pareto", "epsilon"), "with solver: nlp, method epsilon sets each "
                                       "bound through a parameter of the file: give `parameter:` (e.g. "
                                       "`epsilon: {objective: T, parameter: eps, ...}` with `tf <= eps` among "
                                       "the constraints)" + (f"; the file's parameters: {', '.join(known)}"
                                                             if known else ""))])
    if str(name) not in known:
        raise SpecError([located.issue(("pareto", "epsilon", "parameter"), f"epsilon.parameter `{name}` is not "
                                       f"a parameter of the file (give it under `parameters:` and bound the "
                                       f"objective with it, e.g. `tf <= {name}`)")])
    if not _used_in_constraints(located.data, str(name)):
        # unseen39 F2: a parameter that bounds nothing gave a "front" whose every point broke
        # its bound, exit 0 (the run now checks every point's bound as well)
        raise SpecError([located.issue(("pareto", "epsilon", "parameter"), f"epsilon.parameter `{name}` bounds "
                                       f"nothing: no constraint, link, time or named expression of the file "
                                       f"uses it; bound the constrained objective with it, e.g. `tf <= {name}`")])


def _used_in_constraints(doc: Any, name: str) -> bool:
    """Whether ``name`` appears in a text under ``constraints:``, ``links:``, ``time:`` or
    ``expressions:`` anywhere in the file outside ``pareto:``."""
    word = re.compile(rf"(?<![\w.]){re.escape(name)}(?!\w)")

    def texts(node, inside: bool):
        if isinstance(node, dict):
            for key, value in node.items():
                if key != "pareto":
                    yield from texts(value, inside or key in ("constraints", "links", "time", "expressions"))
        elif isinstance(node, list):
            for value in node:
                yield from texts(value, inside)
        elif inside and isinstance(node, str):
            yield node

    return any(word.search(t) for t in texts(doc, False))


def _epsilon_objectives(located: Located, loaded) -> None:
    """What solver nlp's epsilon method can report: the NLP minimises the file's objective,
    so the first Pareto objective is that one, as written (a sum in any order; in a file of
    phases the top-level objective plus each phase's, ``phase.integral(...)``); the others
    are read from the phases' final times and durations. An integral written as the first
    objective but differing from the file's was reported with the file's value (unseen22
    FC2: integral(2*u**2) printed as integral(u**2), 50 % off, exit 0; unseen39 F1: one
    phase's integral of two, in a file of phases, 2x off), and an unknown phase or an
    integral among the others ended in a traceback (unseen39 F3)."""
    from ..hints import did_you_mean
    from ..study.pareto_nlp import evaluate

    objectives = (located.data.get("pareto") or {}).get("objectives") or {}
    texts = {k: (o.get("expr") if isinstance(o, dict) else o) for k, o in objectives.items()}
    if not texts:
        return
    own = _file_objective(located.data)
    first, first_text = next(iter(texts.items()))
    if own is not None and _summands(str(first_text)) not in (_summands(own), _summands("objective")):
        raise SpecError([located.issue(("pareto", "objectives", first),
                                       f"with solver: nlp the first Pareto objective is the one the NLP "
                                       f"minimises, the file's objective `{own}`; `{first}: {first_text}` "
                                       f"differs: write it as the file's objective (or `{first}: objective`), "
                                       f"or make the quantity you want the file's objective")])
    phases = [ph.name for ph in loaded.problem.phases]
    names = {"objective": 1.0, "tf": 1.0, "duration": 1.0} | {f"{p}.{w}": 1.0 for p in phases
                                                               for w in ("tf", "duration")}
    for key, text in list(texts.items())[1:]:
        unknown = [p for p in re.findall(r"(?<![\w.])([A-Za-z_]\w*)\.\w", str(text)) if p not in phases]
        if unknown:
            raise SpecError([located.issue(("pareto", "objectives", key), f"`{key}: {text}`: unknown phase "
                                           f"'{unknown[0]}' (the phases: {', '.join(phases)})"
                                           + did_you_mean(unknown[0], phases))])
        try:
            evaluate(str(text), names)
        except (ValueError, SyntaxError):
            raise SpecError([located.issue(("pareto", "objectives", key),
                                           f"with solver: nlp the objectives after the first are read from the "
                                           f"phases' final times and durations (tf, phase.duration, numbers, + - "
                                           f"* /; the phases: {', '.join(phases)}); `{key}: {text}` is not. Where "
                                           f"one of the two objectives is a time, make the other the file's "
                                           f"objective and the first Pareto objective; for two objectives that "
                                           f"are not times, sweep a bound with `ocdsl study` (a constraint such "
                                           f"as `{text} <= eps` in the file, docs/studies.md)")]) from None


def _file_objective(doc: dict[str, Any]) -> str | None:
    """The objective the NLP minimises, as one text: ``problem: objective:`` without its sense,
    or in a file of phases the top-level one plus each phase's (``phase.integral(...)``, a
    phase's bare ``integral(`` prefixed with its name). None where it cannot be written so
    (a phase objective other than integrals): then only ``objective`` names it."""
    def bare(text: Any) -> str | None:
        return re.sub(r"^\s*(minimize|maximize)\s+", "", text.strip()) if isinstance(text, str) else None

    problem = doc.get("problem")
    if isinstance(problem, dict):
        return bare(problem.get("objective"))
    terms = [t for t in _summand_list(bare(doc.get("objective")) or "0") if t != "0"]
    for name, ph in (doc.get("phases") or {}).items():
        own = ph.get("objective") if isinstance(ph, dict) else None
        if own is None:
            continue
        for t in _summand_list(str(own)):
            if not re.fullmatch(r"integral\(.*\)", t):
                return None
            terms.append(f"{name}.{t}")
    return " + ".join(terms) or "0"


_EXPONENT_SIGN = re.compile(r"(?<![A-Za-z_0-9.])(\d+\.?\d*|\.\d+)[eE]$")     # the + of 1e+5


def _summand_list(text: str) -> list[str]:
    """The top-level summands of ``text`` without spaces (a leading ``+`` dropped)."""
    text = "".join(text.split())
    out, depth, start = [], 0, 0
    for i, c in enumerate(text):
        depth += c in "(["
        depth -= c in ")]"
        if c == "+" and depth == 0 and i > start and not _EXPONENT_SIGN.search(text[:i]):
            out.append(text[start:i])
            start = i + 1
    out.append(text[start:])
    return [t.lstrip("+") for t in out if t.lstrip("+")]


def _summands(text: str) -> list[str]:
    return sorted(_summand_list(text))


def _stand_in(doc: dict[str, Any], located: Located) -> tuple[dict, dict]:
    """The multi-phase problem file a closed-form Pareto file stands for, and the line of
    each of its entries in the original file."""
    lines: dict[tuple, int] = {(): 1}

    def at(new: tuple, old: tuple) -> None:
        lines[new] = located.line(old)

    out: dict[str, Any] = {k: doc[k] for k in ("name", "description", "model", "parameters") if k in doc}
    for k in out:
        lines.update({p: n for p, n in located.lines.items() if p[:1] == (k,)})
    phases = doc.get("phases")
    if not isinstance(phases, dict) or not phases:
        raise SpecError([located.issue(("phases",), "a closed-form Pareto file needs phases: "
                                       "{name: {duration: [lo, hi], fix: {control: value}}}")])
    out["phases"] = {}
    for name, ph in phases.items():
        where = ("phases", name)
        if not isinstance(ph, dict) or set(ph) - {"duration", "fix"}:
            raise SpecError([located.issue(where, f"phase '{name}': give duration: and fix: only")])
        cons = []
        fix = ph.get("fix") or {}
        if not isinstance(fix, dict):
            raise SpecError([located.issue(where + ("fix",), "fix: maps controls to values, e.g. {delta: 0}")])
        for control, value in fix.items():
            at(("phases", name, "constraints", len(cons)), where + ("fix", control))
            cons.append(f"{control} == {value}")
        d = ph.get("duration")
        if d is not None:
            lo, hi = (d, d) if not isinstance(d, list) or len(d) != 2 else d
            at(("phases", name, "constraints", len(cons)), where + ("duration",))
            cons.append(f"{lo} <= tf <= {hi}")
        out["phases"][name] = {"time": {"t0": 0, "tf": "free"}, "constraints": cons}
        at(("phases", name), where)
    problem = doc.get("problem") or {}
    texts = problem.get("constraints", []) if isinstance(problem, dict) else None
    if not isinstance(texts, list):
        raise SpecError([located.issue(("problem",), "problem: holds constraints: [...] in a closed-form "
                                       "Pareto file")])
    out["links"] = [_durations(t) for t in texts]
    for i in range(len(texts)):
        at(("links", i), ("problem", "constraints", i))
    objectives = ((doc.get("pareto") or {}).get("objectives") or {})
    terms = [_durations(o.get("expr") if isinstance(o, dict) else o) for o in objectives.values()]
    out["objective"] = "minimize " + (" + ".join(f"({t})" for t in terms) if terms else "0")
    at(("objective",), ("pareto", "objectives"))
    return out, lines


def _durations(text: Any) -> Any:
    return re.sub(r"\b([A-Za-z_]\w*)\.duration\b", r"\1.tf", text) if isinstance(text, str) else text
