"""The package's name and installed version: what every entry point's ``--version`` and every
report says it was made with (standard library only, so that a ``--version`` loads nothing else)."""
from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

PACKAGE = "rig_identification"


def package_version() -> str:
    """The installed version of this package (``importlib.metadata``), or "unknown (not
    installed)" when it is run from a source tree that was not installed."""
    try:
        return version(PACKAGE)
    except PackageNotFoundError:
        return "unknown (not installed)"
