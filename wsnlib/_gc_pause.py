"""Pausing Python's cyclic garbage collector around a block of work.

A collection can start at any allocation and runs the finalizers of the garbage it finds.  Two
kinds of work pause it:

* :mod:`ast` parsing (:mod:`wsnlib.batch_selection`), which a finalizer must not interrupt.  One
  that formats a traceback (asyncio logging a task of a stopped notebook kernel, say) makes
  Python 3.11 parse source for the traceback's carets, and a parse nested in another one's tree
  construction fails with "SystemError: AST constructor recursion depth mismatch"
  (python/cpython#106905).  In a long-lived process (a Jupyter session, a test run) such garbage
  may be waiting.
* building many small lists at once (Fusion's input rows where its updates run from Python,
  :mod:`wsnlib.orientation._fusion_updates`), which would start the collector over and over for
  nothing (8× slower).
"""

from __future__ import annotations

import contextlib
import gc
from collections.abc import Iterator


@contextlib.contextmanager
def paused_collector() -> Iterator[None]:
    """No cyclic garbage collection inside the block (it runs again after it, if it ran before)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()
