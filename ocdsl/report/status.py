"""One status vocabulary for every report, the index and the terminal: the solver's
status, the verification's, the certificate's and the expect checks', each a badge, and
the overall verdict, which is :attr:`ocdsl.result.Result.ok` (the exit code of
``ocdsl run``). Read from ``result.json`` only.
"""
from __future__ import annotations

import datetime as _dt
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ocdsl.result import Result, certificate_verdict
from ocdsl.result_views import shows_a_solution

SOLVER_GOOD = ("optimal", "acceptable", "feasible", "stable")
# verification status -> badge class (docs/verification.md)
VERIFICATION_CLASS = {"verified": "pass", "not_applicable": "neutral", "failed": "fail", "error": "fail",
                      "skipped": "neutral"}
VERIFICATION_TEXT = {"verified": "verified", "not_applicable": "not applicable", "failed": "failed",
                     "error": "error", "skipped": "skipped", None: "not recorded"}


@dataclass(frozen=True)
class Badge:
    label: str      # what is judged: "solver", "verification", ...
    text: str       # its verdict, in the one vocabulary
    cls: str        # pass | fail | warn | neutral
    title: str = ""  # the reason, shown on hover and in the summary table


def certificate_passed(cert: Any) -> bool | None:
    """The certificate's own verdict: True passed, False failed, None when there is none,
    it was skipped, inconclusive or could not be evaluated (ocdsl.result.certificate_verdict)."""
    return {"passed": True, "failed": False}.get(certificate_verdict(cert))


def certificate_reason(cert: Any) -> str:
    if not isinstance(cert, dict):
        return ""
    if cert.get("error"):
        return f"could not be evaluated: {cert['error']}"
    if cert.get("skipped"):
        return f"skipped: {cert['skipped']}"
    phases = cert.get("phases") if isinstance(cert.get("phases"), dict) else {"": cert}
    parts = []
    for p, c in phases.items():
        if not isinstance(c, dict):
            continue
        pre = f"{p}: " if p else ""
        if c.get("error"):
            parts.append(f"{pre}could not be evaluated: {c['error']}")
        elif c.get("failed"):
            parts.append(f"{pre}failed: {', '.join(map(str, c['failed']))}")
        elif c.get("inconclusive"):
            parts.append(f"{pre}inconclusive: {c['inconclusive']}")
        elif c.get("skipped"):
            parts.append(f"{pre}skipped: {c['skipped']}")
    return "; ".join(parts)


def badges(res: Result) -> list[Badge]:
    """Solver, verification, certificate (when there is one), expect checks (when there are
    any) and the overall verdict, in that order."""
    out = [Badge("solver", res.status, "pass" if res.status in SOLVER_GOOD else "fail",
                 (res.message or "").splitlines()[0] if res.message else "")]
    v = res.verification if isinstance(res.verification, dict) else None
    vs = v.get("status") if v else None
    cls = VERIFICATION_CLASS.get(vs, "neutral")
    text = VERIFICATION_TEXT.get(vs, str(vs))
    if vs in ("failed", "error") and v.get("mode") == "warn":
        cls, text = "warn", f"{text} (warn only)"
    out.append(Badge("verification", text, cls, (v or {}).get("summary", "") if v else
                     "this run folder was written before ocdsl verified its results"))
    cv = certificate_verdict(res.certificate)
    if res.certificate:
        text = {"passed": "pass", "failed": "failed", "inconclusive": "inconclusive",
                "skipped": "skipped"}.get(cv, "not evaluated")
        cls = {"passed": "pass", "failed": "fail"}.get(cv, "neutral")
        if cv == "passed" and not shows_a_solution(res):
            # conditions that hold at a last iterate say nothing of a solution (unseen43 F10:
            # a green "pass" on an interrupted run)
            text, cls = "pass on the last iterate (not a solution)", "neutral"
        out.append(Badge("certificate", text, cls, certificate_reason(res.certificate)))
    if res.expect:
        n_ok = sum(bool(c.get("passed")) for c in res.expect)
        out.append(Badge("expect", f"{n_ok} of {len(res.expect)} pass",
                         "pass" if n_ok == len(res.expect) else "fail",
                         "; ".join(f"{c.get('name')} failed" for c in res.expect if not c.get("passed"))))
    out.append(overall(res))
    return out


def overall(res: Result) -> Badge:
    """:attr:`Result.ok`, the exit code's verdict, with what stands in its way."""
    reasons = []
    if res.status not in ("optimal", "stable", "feasible"):
        reasons.append(f"solver {res.status}")
    bad = [c for c in res.expect if not c.get("passed")]
    if bad:
        reasons.append(f"{len(bad)} expect check{'s' if len(bad) > 1 else ''} failed")
    if not res.verification_ok:
        vs = (res.verification or {}).get("status")
        reasons.append("not verified" if vs is None else f"verification {VERIFICATION_TEXT.get(vs, vs)}")
    if certificate_verdict(res.certificate) == "failed":
        reasons.append(f"certificate {certificate_reason(res.certificate)}")
    if res.ok:
        return Badge("overall", "ok (exit 0)", "pass")
    # an interrupted run exits as the signal says, not 1 (unseen43 F3)
    code = (143 if "SIGTERM" in (res.message or "") else 130) if res.status == "interrupted" else 1
    return Badge("overall", f"not ok (exit {code})", "fail", "; ".join(reasons))


def ocdsl_build() -> dict[str, str]:
    """The ocdsl version, the commit of its source tree (``unknown`` outside a git
    checkout; ``+changes`` when the tree differs from it) and the date, for every report."""
    from ocdsl import __version__

    root = Path(__file__).resolve().parents[2]
    commit = "unknown"
    try:
        proc = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, timeout=10)
        if proc.returncode == 0 and proc.stdout.strip():
            commit = proc.stdout.strip()
            dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no",
                                    "--", "ocdsl"], capture_output=True, text=True, timeout=10)
            if dirty.returncode == 0 and dirty.stdout.strip():
                commit += "+changes"
    except (OSError, subprocess.SubprocessError):
        pass
    date = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    return {"version": __version__, "commit": commit, "date": date}


def unjudged_flight(res: Result, phase: str | None) -> str:
    """The sentence " Not judged: ..." where the verification left this phase's flight from
    x(t0) unjudged (an open-loop-unstable phase, judged piece by piece): its line is that flight's
    divergence, not a miss of the solution (unseen33 F15: a verified run's figure showed
    only a flight 5.6e9 off, with no word why)."""
    v = res.verification if isinstance(res.verification, dict) else {}
    for c in v.get("checks") or []:
        if c.get("name") == "dynamics from x(t0)" and c.get("passed") is None and \
                (phase is None or c.get("phase") in (phase, None)):
            return (" Not judged by the verification: " + str(c.get("not_judged", "")).split(":")[0]
                    + "; the phase was judged piece by piece.")
    return ""


def what_is_drawn(res: Result) -> str:
    """What a run's rows are: a solution, a cut-short refinement's best completed mesh, or a
    failed solve's last iterate (unseen33 F3: an infeasible run's last iterate and a solve
    that never started's guess were drawn as "solution")."""
    from ocdsl.result_views import completed_solution

    if res.has_solution:
        return "solution"
    if completed_solution(res):
        return "best completed solve"
    # a solve that never started has only its guess (unseen43 F6: shown as a last iterate)
    return "last iterate (not a solution)" if res.iterations else "guess (the solve did not start)"
