"""Numba's on-disk cache of the orientation kernels: one folder per version of their sources.

numba keys a cached function by the timestamp of *its own* file only.  A kernel that calls a
jitted function of another file (``filter_stream`` calls ``_scalar_kernels.madgwick_update``;
the smoother runs the Kalman loop) holds its own compiled copy of it, so after that other file
changes the cache would silently keep running the old machine code.  And a process that
imported the old sources (a Jupyter kernel left open across an edit or a ``git pull``) but
compiles after the edit would store old machine code where the new sources look for theirs.

So every kernel of this package caches below a folder named by the SHA-256 of the package's
sources *as this process imported them* (:data:`SOURCES_DIGEST`, read once, when the package is
imported): ``__pycache__/numba-<digest[:16]>/`` beside the sources, or
``$NUMBA_CACHE_DIR/wsnlib-orientation/numba-<digest[:16]>/`` when that variable is set.  A process
running old code reads and writes only the old version's folder; the first process of new
sources compiles once into the new one (seconds for a small kernel, about 40 s for the Kalman
filter's family).  At import, the cache files of the other versions are deleted (their folders
stay, so that a process still running old code can keep saving into its own without an error).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

import numba

from wsnlib._files import sources_digest

PACKAGE_DIR = Path(__file__).parent
#: SHA-256 of the package's ``*.py`` files (names and bytes) when this process imported it.
SOURCES_DIGEST = sources_digest(PACKAGE_DIR)
FOLDER_PREFIX = "numba-"


def versions_folder() -> Path:
    """The folder of every version's cache: ``__pycache__`` here, or below ``$NUMBA_CACHE_DIR``."""
    user = numba.config.CACHE_DIR
    return Path(user) / "wsnlib-orientation" if user else PACKAGE_DIR / "__pycache__"


def version_folder(digest: str = SOURCES_DIGEST) -> Path:
    """The cache folder of the sources with SHA-256 ``digest`` (default: those this process imported)."""
    return versions_folder() / f"{FOLDER_PREFIX}{digest[:16]}"


@contextlib.contextmanager
def caching_into_this_version(subfolder: str = "") -> Iterator[None]:
    """numba's ``CACHE_DIR`` is :func:`version_folder` (or a ``subfolder`` of it: another package whose
    kernels call these) while the kernel modules are imported.

    A jitted function picks its cache folder when it is defined; the user's setting is restored
    afterwards, so numba code outside this package is not affected.
    """
    folder = version_folder() / subfolder if subfolder else version_folder()
    saved = numba.config.CACHE_DIR
    numba.config.CACHE_DIR = str(folder)
    try:
        yield
    finally:
        numba.config.CACHE_DIR = saved


def drop_other_versions() -> int:
    """Delete the ``*.nbi``/``*.nbc`` files of the other versions' folders; return how many.

    Errors (a read-only folder, a file another process just removed) are ignored.
    """
    current = version_folder()
    dropped = 0
    for folder in versions_folder().glob(f"{FOLDER_PREFIX}*"):
        if folder == current:
            continue
        for path in folder.rglob("*.nb[ic]"):
            with contextlib.suppress(OSError):
                path.unlink()
                dropped += 1
    return dropped


def cache_dir(kernel) -> Path:
    """Folder where numba keeps ``kernel``'s cache (below :func:`version_folder`)."""
    return Path(kernel._cache._cache_path)
