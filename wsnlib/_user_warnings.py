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
    """``warnings.warn(message, category)`` attributed to the innermost frame outside the package (a
    notebook cell, a script, a test), so that the warning names the user's call; from a command line
    of the package (``python -m wsnlib…``, called by the interpreter's own frozen ``runpy``), to the
    package's outermost frame."""
    frame, level = sys._getframe(1), 2  # level 2: warn_user's caller
    while frame.f_code.co_filename.startswith(PACKAGE_DIR):
        outer = frame.f_back
        if outer is None or outer.f_code.co_filename.startswith("<frozen"):
            break
        frame, level = outer, level + 1
    warnings.warn(message, category, stacklevel=level)
