"""``rig-identify thesis-table``: the thesis's case studies, simulated noise-free, identified by the
rig model and by the thesis's method (:mod:`rig_identification.pipeline.thesis_table`)."""
from __future__ import annotations

import json

from ..pipeline.thesis_table import print_summary, print_table, run_case
from .progress import step


def cmd_thesis_table(args) -> int:
    """``rig-identify thesis-table``: one progress step per case; returns the exit status."""
    rows = []
    for name in args.cases or [f"case{i:02d}" for i in range(1, 18)]:
        step(f"{name}: simulating and identifying (the rig model and the thesis's method)")
        rows.append(run_case(name))
        args.progress.finish()
        if not args.json:
            print_table(rows[-1:])
    if args.json:
        print(json.dumps(rows))
    else:
        print_summary(rows)
    return 0
