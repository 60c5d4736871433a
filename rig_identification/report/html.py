"""HTML building blocks of the identification report (:mod:`rig_identification.report.rig_page`): number formatting that
never prints ``nan`` or ``inf``, tables, the page's style sheet and the page frame.

Every number on the page goes through :func:`num` (or :func:`pct`): a value that is None or
not finite is shown as :data:`MISSING`, never as ``nan``; an entry the recording does not
determine is shown as :data:`NOT_DETERMINED` by the callers.  Every JSON file goes through
:func:`json_safe` (null, never NaN).
"""
from __future__ import annotations

import html
import math
from collections.abc import Iterable, Sequence

import numpy as np

from ..io.export import NOT_DETERMINED  # an entry the recording does not determine (verdict not_identifiable)
from .folder import GENERATOR  # the mark of a page this package wrote

MISSING = "—"                       # a number that does not exist (no truth, no CRB, …)


def finite(x) -> bool:
    """True when ``x`` is a real finite number (not None, not NaN, not ±inf)."""
    try:
        return x is not None and math.isfinite(float(x))
    except (TypeError, ValueError):
        return False


def num(x, fmt: str = ".3g") -> str:
    """``x`` formatted with ``fmt`` (a format spec, e.g. ``".2f"``, ``"+.3g"``), or
    :data:`MISSING` when it is None or not finite.  A negative zero prints as 0."""
    if not finite(x):
        return MISSING
    s = format(float(x) + 0.0, fmt)
    if s.startswith("-") and float(s) == 0.0:      # a negative number rounded to zero
        s = ("+" if "+" in fmt else "") + s[1:]
    return s


def pct(x, fmt: str = ".3g") -> str:
    """A fraction ``x`` (dimensionless) as a percentage ("0.12 %"), or :data:`MISSING`."""
    return MISSING if not finite(x) else f"{num(100 * float(x), fmt)} %"


def esc(x) -> str:
    """HTML-escaped text of ``x``."""
    return html.escape(str(x))


class Cell:
    """A table cell with a CSS class (``cls``) and optional raw HTML (``raw``; else escaped text)."""

    def __init__(self, text, cls: str = "", raw: bool = False):
        self.text, self.cls, self.raw = text, cls, raw

    def html(self, tag: str = "td") -> str:
        body = str(self.text) if self.raw else esc(self.text)
        return f'<{tag} class="{self.cls}">{body}</{tag}>' if self.cls else f"<{tag}>{body}</{tag}>"


def cell(x, tag: str = "td") -> str:
    return x.html(tag) if isinstance(x, Cell) else f"<{tag}>{esc(x)}</{tag}>"


def table(head: Sequence, rows: Iterable[Sequence], cls: str = "", ident: str = "",
          caption: str = "", row_cls: Sequence[str] | None = None, text_cols: Iterable[int] = ()) -> str:
    """An HTML table: ``head`` (column titles), ``rows`` (lists of cells: text, or
    :class:`Cell`), ``cls``/``ident`` the table's class and id, ``caption`` (text), ``row_cls``
    one CSS class per row ("" for none), ``text_cols`` the indices of the columns of text
    (left-aligned; numbers are right-aligned)."""
    rows = list(rows)
    row_cls = list(row_cls) if row_cls is not None else [""] * len(rows)
    text_cols = set(text_cols)

    def put(x, i, tag):
        if i in text_cols and not isinstance(x, Cell):
            x = Cell(x, "text")
        return cell(x, tag)
    h = "".join(put(x, i, "th") for i, x in enumerate(head))
    body = "".join((f'<tr class="{c}">' if c else "<tr>") + "".join(put(x, i, "td") for i, x in enumerate(r))
                   + "</tr>" for r, c in zip(rows, row_cls))
    attrs = (f' class="{cls}"' if cls else "") + (f' id="{ident}"' if ident else "")
    cap = f"<caption>{esc(caption)}</caption>" if caption else ""
    return f"<table{attrs}>{cap}<thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>"


def json_safe(x):
    """``x`` with every non-finite float replaced by None and numpy values by Python ones
    (report.json never holds NaN or infinity)."""
    if isinstance(x, dict):
        return {str(k): json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    if isinstance(x, np.ndarray):
        return json_safe(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    return x


CSS = """
body { font-family: system-ui, "DejaVu Sans", sans-serif; margin: 1.5em auto; max-width: 1150px; color: #222;
       padding: 0 1em; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; }
h2 { font-size: 1.2em; margin-top: 1.8em; border-bottom: 1px solid #ccc; }
h3 { font-size: 1.02em; margin: 1.2em 0 0.3em; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.92em; }
caption { text-align: left; font-weight: 600; padding: 0.2em 0; }
th, td { border: 1px solid #ccc; padding: 3px 8px; text-align: right; vertical-align: top; }
th { background: #f0f0f0; } td:first-child, th:first-child { text-align: left; }
td.text, th.text { text-align: left; }
table.tensor td:first-child, table.checks td:first-child { white-space: nowrap; }
table.checks td:nth-child(3), table.checks td:nth-child(4) { white-space: nowrap; }
table.meta td, table.meta th { text-align: left; border: none; padding: 1px 12px 1px 0; }
table.meta th { background: none; color: #555; font-weight: normal; }
table.checks td:last-child { text-align: left; max-width: 560px; }
table.ident td:last-child { text-align: left; max-width: 640px; }
td.undet { color: #a40; font-style: italic; text-align: center; }
td.pass { color: #176117; font-weight: 600; text-align: center; }
td.fail { color: #b00; font-weight: 700; text-align: center; }
td.na { color: #777; text-align: center; }
tr.weak td { background: #fff1f0; }
tr.failed td { background: #fff1f0; }
table.matrix td { min-width: 6em; }
img { max-width: 100%; border: 1px solid #ddd; margin: 0.4em 0; }
@media print, (max-width: 900px) {
  body { margin: 0.5em auto; padding: 0 0.3em; }
  table { font-size: 0.78em; }
  th, td { padding: 2px 4px; }
  h2 { break-after: avoid; }
  table, img, .verdict { break-inside: avoid; }
}
.verdict { border: 2px solid; border-radius: 6px; padding: 0.6em 1em; margin: 1em 0; }
.verdict p { margin: 0.3em 0; }
.verdict.ok { border-color: #2a7a2a; background: #f1f9f1; }
.verdict.model_error { border-color: #b00; background: #fff3f1; }
.verdict.not_identifiable { border-color: #c70; background: #fff8ec; }
.verdict.none { border-color: #888; background: #f6f6f6; }
.verdict .sentence { font-size: 1.08em; font-weight: 600; }
.untrusted { color: #b00; font-weight: 700; }
.hypothesis { border-left: 4px solid #c70; padding-left: 0.8em; }
.finding { border-left: 4px solid #2a7a2a; padding-left: 0.8em; }
.note { color: #555; font-size: 0.9em; } .warn { color: #a40; }
"""


def page(title: str, body: Sequence[str]) -> str:
    """The whole HTML document: ``title`` (text) and the ``body`` parts (HTML)."""
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">" + GENERATOR
            + f"<title>{esc(title)}</title><style>{CSS}</style></head>\n<body>\n" + "\n".join(body)
            + "\n</body></html>\n")


__all__ = ["MISSING", "NOT_DETERMINED", "finite", "num", "pct", "esc", "Cell", "table",
           "json_safe", "CSS", "page"]
