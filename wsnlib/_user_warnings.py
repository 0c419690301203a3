"""Warnings that point at the user's line: the first caller outside ``wsnlib``.

A fixed ``stacklevel`` fits one call depth only, and the library's checks are reached from
public functions at different depths (``kalman_orientation`` calls the input checks directly, the
peers through a shared batch driver); Python 3.12's ``skip_file_prefixes`` does this, but the
lock's Python is 3.11.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

PACKAGE_DIR = str(Path(__file__).resolve().parent)


def warn_user(message: str, category: type[Warning] = UserWarning) -> None:
    """``warnings.warn(message, category)`` attributed to the innermost frame outside the package
    (a notebook cell, a test, a script), so that the warning names the user's call."""
    frame, level = sys._getframe(1), 2  # level 2: warn_user's caller
    while frame is not None and frame.f_code.co_filename.startswith(PACKAGE_DIR):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, category, stacklevel=level)
