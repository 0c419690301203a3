"""Pausing Python's cyclic garbage collector around work that must not run finalizers.

A collection can start at any allocation and runs the finalizers of the garbage it finds.  Two
places of the library cannot have that:

* :mod:`ast` parsing (:mod:`wsnlib.batch_selection`).  A finalizer that formats a traceback (asyncio
  logging a task of a stopped notebook kernel, say) makes Python 3.11 parse source for the
  traceback's carets; a parse nested in another one's tree construction fails with "SystemError:
  AST constructor recursion depth mismatch" (python/cpython#106905).  In a long-lived process (a
  Jupyter session, a test run) that garbage may be waiting.
* building many small lists at once (:func:`wsnlib.orientation.peers` Fusion's input rows), which
  would start the collector over and over for nothing (8× slower).
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
