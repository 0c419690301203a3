"""Project folders, built from this package's location (never from the working directory).

Generated content (simulated raw recordings, figures, tables, executed notebooks) goes below
``ROOT`` unless the environment variable ``WSNLIB_OUTPUT_DIR`` names another folder; the
tests use that to run the batch into temporary folders without touching the checkout.
Read the folders through the functions below (not module constants), so a change of the
variable inside a running process is honoured.
"""

from __future__ import annotations

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOKS = ROOT / "notebooks"

#: Name of the Jupyter kernel that ``make`` registers inside the project's virtual environment.
KERNEL_NAME = "wsn-motion"

OUTPUT_ENV_VAR = "WSNLIB_OUTPUT_DIR"

#: Environment variable that marks an unattended (batch) run, set by :mod:`wsnlib.reproduce`.
BATCH_ENV_VAR = "WSNLIB_BATCH"
_TRUE, _FALSE = ("1", "true", "yes", "on"), ("", "0", "false", "no", "off")


def in_batch() -> bool:
    """True when running unattended (``WSNLIB_BATCH`` = 1, true, yes or on, any case): static figures,
    no widgets, too-small text an error.  Unset, empty, 0, false, no or off: interactive.

    Raises ``ValueError`` naming the variable for any other value (a typo must not pass as "no").
    """
    value = os.environ.get(BATCH_ENV_VAR, "").strip().lower()
    if value not in _TRUE + _FALSE:
        raise ValueError(f"${BATCH_ENV_VAR} must be one of {', '.join(_TRUE + _FALSE[1:])} (or unset), "
                         f"got {os.environ[BATCH_ENV_VAR]!r}")
    return value in _TRUE


def output_root() -> Path:
    """Folder below which generated content is written (``ROOT`` or ``$WSNLIB_OUTPUT_DIR``)."""
    override = os.environ.get(OUTPUT_ENV_VAR)
    return Path(override).resolve() if override else ROOT


def data_raw() -> Path:
    """Raw recordings (simulated ones are written here), created on first use."""
    return _ensure(output_root() / "data" / "raw")


def data_processed() -> Path:
    """Tables computed by the notebooks, and the batch manifest."""
    return _ensure(output_root() / "data" / "processed")


def figures() -> Path:
    """Figures saved by :func:`wsnlib.plotting.savefig`."""
    return _ensure(output_root() / "figures")


def executed_notebooks() -> Path:
    """Executed copies of the notebooks (gitignored)."""
    return _ensure(output_root() / "build" / "executed")


def _ensure(path: Path) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    return path
