"""The report's folder and header fields (:mod:`~rig_identification.report.rig_page`): who and
what the report is for (:class:`Job`), the rig's label, and the refusal to replace anything
but an earlier report (:func:`check_report_dir`)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..io.rig import Rig

#: The mark every report page carries (:mod:`~rig_identification.report.html`): a folder whose
#: index.html has it holds an earlier report (:func:`check_report_dir`).
GENERATOR = '<meta name="generator" content="rig-identify report">'


@dataclass(frozen=True)
class Job:
    """Who and what the report is for, as the lab gives it (``rig-identify inertia --vehicle-name
    --customer --operator``): each a line of text or None (not given, not shown)."""

    vehicle: str | None = None
    customer: str | None = None
    operator: str | None = None

    def rows(self) -> list[list[str]]:
        """The header's rows for the fields given: [label, text]."""
        return [[label, text] for label, text in (("vehicle", self.vehicle), ("customer", self.customer),
                                                  ("operator", self.operator)) if text]

    def to_dict(self) -> dict[str, str | None]:
        """report.json's fields (``vehicle_name``: ``vehicle`` there is where the vehicle lies)."""
        return {"vehicle_name": self.vehicle, "customer": self.customer, "operator": self.operator}


class ReportError(ValueError):
    """The result cannot be reported (the thesis baseline has no fit output series), or
    the report folder would replace something that is not an earlier report."""


def check_report_dir(out: Path) -> None:
    """Refuse to replace a file, or a non-empty folder that is not an earlier report."""
    if not out.exists():
        return
    if not out.is_dir():
        raise ReportError(f"{out}: exists and is not a folder (refusing to replace it with the report)")
    index = out / "index.html"
    if any(out.iterdir()) and not (index.is_file() and GENERATOR in index.read_text(errors="replace")[:2000]):
        raise ReportError(f"{out}: exists and is not an earlier rig-identify report (refusing to replace it); "
                          "give a new folder")


def rig_label(rig: Rig) -> str:
    """The rig's name (rig.yaml ``name``) with where it was read from, or only the latter when
    rig.yaml names none."""
    return f"{rig.name} ({rig.source})" if rig.name else str(rig.source)


__all__ = ["GENERATOR", "Job", "ReportError", "check_report_dir", "rig_label"]
