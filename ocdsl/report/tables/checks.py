"""Tables of the checks: expect, verification, certificate (per check) and switch times
(per control), each with its comparison and tolerance."""
from __future__ import annotations

from typing import Any

from ocdsl.result import Result
from ocdsl.report.tables.cells import cell, finite_or_none, fmt, table, verdict


COMPARE_TEXT = {"equal": "|error| ≤ tol", "at_most": "ocdsl ≤ ref + tol", "at_least": "ocdsl ≥ ref − tol"}


def tolerance_text(c: dict) -> str:
    """An expect check's band: the larger of rtol·|reference| and atol."""
    parts = []
    if c.get("rtol") is not None:
        parts.append(f"rtol {fmt(c['rtol'], 3)}")
    if c.get("atol") is not None:
        parts.append(f"atol {fmt(c['atol'], 3)}")
    return ", ".join(parts) or "—"


def compare_text(c: dict) -> str:
    return COMPARE_TEXT.get(c.get("compare") or "equal", str(c.get("compare")))


def expect_table(res: Result) -> dict | None:
    rows = []
    for c in res.expect or []:
        # the error the tolerance holds: relative under an rtol alone (an absolute 0.003 was
        # shown against "rtol 0.001" for a relative 7.5e-4, unseen33 F5)
        relative = c.get("rtol") and not c.get("atol") and c.get("relative_error") is not None
        rows.append([cell(c.get("name", "?"), "name"), cell(c.get("reference"), "num", 10),
                     cell(c.get("value"), "num", 10),
                     cell(c.get("relative_error") if relative else c.get("error"), "num", 3),
                     cell(compare_text(c), "nowrap"), cell(tolerance_text(c), "nowrap"), verdict(c.get("passed"))])
    return table("expect", "Expected values (the file's expect block: reference, e.g. from the paper) "
                 "against ocdsl's, with the comparison and tolerance of each check.",
                 ["check", "reference", "ocdsl", "error (relative where the tolerance is rtol)", "comparison",
                  "tolerance", "result"], rows)


def verification_table(res: Result) -> dict | None:
    """The independent verification (ocdsl/verify, ``result.json`` ``verification``): one row
    per check, its relative value against the tolerance it is held to."""
    v = res.verification
    if not isinstance(v, dict):
        return None
    rows = []
    for c in v.get("checks") or []:
        what = c.get("name", "?")
        if c.get("phase") and len(res.phases) > 1:
            what += f" ({c['phase']})"
        rows.append([cell(what, "name"), cell(c.get("detail") or "", ""), cell(c.get("value"), "num", 3),
                     cell("≤", ""), cell(c.get("limit"), "num", 3), cell(c.get("where") or "", ""),
                     verdict(c.get("passed"))])
    note = " ".join([v.get("summary") or ""] + [f"Note: {c}." for c in v.get("caveats") or []])
    if v.get("mode") == "warn":
        note += " The file asks for verify: {mode: warn}: a failed check is reported but does not fail the run."
    if not rows:
        rows.append([cell("verification", "name"), cell(v.get("summary") or "", ""), cell(None), cell("", ""),
                     cell(v.get("tolerance"), "num", 3), cell("", ""),
                     {"text": str(v.get("status")), "cls": "fail" if v.get("status") in ("failed", "error") else ""}])
        note = ""
    return table("verification", "Independent verification of the returned trajectory (ocdsl/verify, "
                 "docs/verification.md): each value is relative and held to the tolerance beside it.",
                 ["check", "how", "value", "", "tolerance", "worst at", "result"], rows, note)


# certificate check -> (its measured value, the tolerance key, comparison, what it measures)
CERTIFICATE_CHECKS = {
    "hamiltonian": ("relative_max_deviation", "hamiltonian_max", "≤",
                    "max |H − expected| / scale (constant H where expected is none)"),
    "stationarity": ("max_relative", "stationarity", "≤", "max |∂H/∂u| / term size at interior nodes"),
    "switching": ("agreement", "sign_agreement", "≥", "share of saturated nodes where the sign of ∂H/∂u "
                  "picks that bound"),
    "path_multipliers": ("complementarity", "complementarity", "≤",
                         "max |μ (g − bound)| / term size (complementarity)"),
}


def certificate_phases(cert: Any) -> list[tuple[str | None, dict]]:
    if not isinstance(cert, dict):
        return []
    if isinstance(cert.get("phases"), dict):
        return [(p, c) for p, c in cert["phases"].items() if isinstance(c, dict)]
    return [(None, cert)]


def certificate_table(cert: Any) -> dict | None:
    """The optimality certificate (necessary conditions where costates exist): one row per
    check with its measured value, comparison and tolerance."""
    rows = []
    for phase, c in certificate_phases(cert):
        pre = f"{phase}: " if phase else ""
        if c.get("error") or c.get("skipped"):
            rows.append([cell(pre + "certificate", "name"), cell(c.get("error") or c.get("skipped"), ""),
                         cell(None), cell("", ""), cell(None), verdict(False if c.get("error") else None)])
            continue
        tol = c.get("tolerances") or {}
        for key, (vkey, tkey, op, what) in CERTIFICATE_CHECKS.items():
            d = c.get(key)
            if not isinstance(d, dict):
                continue
            val = d.get(vkey)
            extra = ""
            if key == "hamiltonian":
                exp = finite_or_none(d.get("expected"))
                extra = (f"; expected {fmt(exp + 0.0, 4)}" if exp is not None else "; expected constant")
            rows.append([cell(pre + key.replace("_", " "), "name"), cell(what + extra, ""), cell(val, "num", 3),
                         cell(op, ""), cell(tol.get(tkey), "num", 3), verdict(d.get("passed"))])
    if not rows:
        return None
    return table("certificate", "Optimality certificate: first-order necessary conditions (Pontryagin) "
                 "evaluated with the costates; the re-integration is the verification's (above).",
                 ["check", "what it measures", "value", "", "tolerance", "result"], rows)


def switch_table(cert: Any) -> dict | None:
    """Per control: the share of nodes at a bound and the switch times (bang-bang structure)."""
    rows = []
    for phase, c in certificate_phases(cert):
        per = ((c.get("bang_bang") or {}).get("per_control") or {}) if isinstance(c, dict) else {}
        for u, d in per.items():
            if not isinstance(d, dict):
                continue
            times = [finite_or_none(x) for x in d.get("switch_times") or []]
            times = [x for x in times if x is not None]
            seq = d.get("sequence") or []
            rows.append([cell(f"{phase}: {u}" if phase else u, "name"),
                         cell(100 * float(d.get("fraction_at_bound") or 0.0), "num", 3),
                         cell(len(times)), cell(", ".join(fmt(x, 5) for x in times) or "none", "list"),
                         cell(" ".join(map(str, seq)) if seq else "—", "list")])
    return table("switches", "Switching structure of each control: share of nodes at a bound and the "
                 "switch times (from the certificate).",
                 ["control", "at a bound [%]", "switches", "switch times", "bound sequence"], rows)
