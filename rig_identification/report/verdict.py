"""The validation verdict of the report, first on the page: the verdict in words
(:attr:`~rig_identification.io.verdict.Validation.summary`), what it means for the numbers below, and the checks
as a table (name, what it tests, statistic, threshold, pass/fail, detail).

Verdicts (:mod:`rig_identification.estimation.validation`): ``ok`` — the σ are calibrated;
``model_error`` — the tensor is
not trustworthy and its σ is widened to the spread the checks saw (a lower bound of the
error); ``not_identifiable`` — the entries the recording does not determine are shown as
"not determined", with what to change on the rig or the excitation.
"""
from __future__ import annotations

from ..estimation.inertia_result import InertiaResult
from ..io.verdict import Check, Validation
from .html import NOT_DETERMINED, Cell, bullets, esc, finite, num, table
from .mass import SYMBOL

# what each check tests, and how its statistic reads: "ratio" (×), "chi2" (χ²/dof), "fraction"
# (shown in %), "sigma" (σ)
CHECKS = {
    "segments": ("time segments of the window give the same tensor", "chi2"),
    "sub_bands": ("the lower and upper half of the fit band give the same tensor", "chi2"),
    "input_correlation": ("the residual is not correlated with the input", "chi2"),
    "whiteness": ("no spectral line in the residual (over its local level)", "ratio"),
    "weight": ("the load cells carry rig.yaml's weight", "fraction"),
    "identifiable": ("every entry is determined (largest σ over its scale)", "fraction"),
}


def statistic_text(kind: str, x) -> str:
    """A check's statistic or threshold as text in its unit (see :data:`CHECKS`)."""
    if not finite(x):
        return "—"
    if kind == "fraction":
        return f"{num(100 * x, '.3g')} %"
    if kind == "chi2":
        return f"{num(x, '.3g')} χ²/dof"
    if kind == "sigma":
        return f"{num(x, '.3g')} σ"
    return f"{num(x, '.3g')}×"


def checks_table(v: Validation) -> str:
    """The checks of ``v`` as a table; failed rows highlighted."""
    rows, cls = [], []
    c: Check
    for c in v.checks:
        what, kind = CHECKS.get(c.name, ("", "ratio"))
        verdict = (Cell("pass", "pass") if c.passed else Cell("FAIL", "fail") if c.passed is False
                   else Cell("does not apply", "na"))
        widened = f" (σ widened {c.sigma_factor:.2f}×)" if c.sigma_factor > 1.0 and "widened" not in c.detail else ""
        rows.append([c.name, Cell(what, "text"), statistic_text(kind, c.statistic),
                     "≤ " + statistic_text(kind, c.threshold) if finite(c.threshold) else "—", verdict,
                     Cell(c.detail + widened, "text")])
        cls.append("failed" if c.passed is False else "")
    return table(["check", "what it tests", "statistic", "threshold", "result", "detail"], rows, cls="checks",
                 ident="checks-table", row_cls=cls, text_cols=(1, 5))


def headline(v: Validation) -> str:
    """The verdict sentence: :attr:`~rig_identification.io.verdict.Validation.summary` without the advice it ends
    with (the page lists the advice on its own)."""
    s = v.summary
    tail = "; " + "; ".join(v.advice)
    return s[:-len(tail)] if v.advice and s.endswith(tail) else s


def verdict_html(result: InertiaResult) -> str:
    """The verdict box (HTML, element id ``verdict``): the sentence, what it means for the
    tensor below, the advice, and the precision against the lab's target (element id
    ``precision``: :attr:`~rig_identification.estimation.inertia_result.InertiaResult.precision`)."""
    v = result.validation
    if v is None:
        return ('<div class="verdict none" id="verdict"><p class="sentence">No validation verdict: this fit was not '
                "validated (an identifier run outside the pipeline); its σ are the identifier's own.</p></div>")
    cls = ' untrusted' if v.verdict == "model_error" else ""
    parts = [f'<p class="sentence{cls}">{esc(headline(v))}</p>']
    if v.verdict == "model_error":
        if "not trustworthy" not in v.summary:
            parts.append('<p class="untrusted">The tensor below is not trustworthy: the recording disagrees with the '
                         "rigid-body model. Its σ is widened to the spread the checks saw between time segments and "
                         "frequency sub-bands — a lower bound of the error, not a calibrated σ.</p>")
        parts.append("<p>rig-identify diagnose fits the rig model to every sensor and tests what it leaves "
                     "out.</p>")
    elif v.verdict == "not_identifiable":
        gone = ", ".join(SYMBOL[k] for k in v.undetermined)
        parts.append(f"<p>Shown as “{NOT_DETERMINED}” below (null in report.json): {esc(gone)}. Nothing derived "
                     "from them (principal moments, the ellipsoid) is given.</p>")
        if v.advice:
            parts.append("<p>What to change:</p>" + bullets(v.advice))
    parts.append(f'<p class="precision" id="precision">{esc(result.precision.text())}</p>')
    return f'<div class="verdict {v.verdict}" id="verdict">' + "".join(parts) + "</div>"


__all__ = ["CHECKS", "checks_table", "headline", "verdict_html", "statistic_text"]
