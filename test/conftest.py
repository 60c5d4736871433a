import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("RIG_SHARED", REPO.parent / "shared"))
RECORDINGS = SHARED / "recordings"


def recording(name: str) -> Path:
    p = RECORDINGS / name
    if not p.exists():
        pytest.fail(f"reference recording {p} is missing (../shared/recordings must sit beside the repository)")
    return p
