"""Numba's on-disk cache of the orientation kernels, dropped whenever any of their sources changes.

numba keys a cached function by the timestamp of *its own* file only.  A kernel that calls a
jitted function of another file (``filter_stream`` calls ``_scalar_kernels.madgwick_update``;
the smoother runs the Kalman loop) holds its own compiled copy of it, so after that other
file changes the cache would silently keep running the old machine code.  Here the SHA-256 of
every source file of :mod:`wsnlib.orientation` is written beside the cache; when it differs
(any source edited), the package's cache files are deleted before any kernel is called, and
the first call recompiles (about 10–20 s once).
"""

from __future__ import annotations

import hashlib
from pathlib import Path

STAMP_NAME = "wsnlib-orientation-sources.sha256"
PACKAGE_DIR = Path(__file__).parent


def sources_digest(package_dir: Path = PACKAGE_DIR) -> str:
    """SHA-256 over the names and bytes of every ``*.py`` file of the package, in name order."""
    digest = hashlib.sha256()
    for path in sorted(package_dir.glob("*.py")):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def cache_dir(kernel) -> Path:
    """Folder where numba keeps ``kernel``'s cache (``__pycache__`` here, or under ``NUMBA_CACHE_DIR``)."""
    return Path(kernel._cache._cache_path)


def drop_stale_cache(folder: Path, digest: str) -> bool:
    """Delete the package's ``*.nbi``/``*.nbc`` files in ``folder`` unless its stamp says ``digest``.

    Returns True when files were dropped (the stamp was missing or different).  Errors from a
    read-only folder are ignored: numba then falls back to compiling in memory.
    """
    stamp = folder / STAMP_NAME
    try:
        if stamp.read_text(encoding="ascii").strip() == digest:
            return False
    except OSError:
        pass
    modules = {path.stem for path in PACKAGE_DIR.glob("*.py")}
    try:
        for path in folder.glob("*.nb[ic]"):
            if path.name.split(".", 1)[0] in modules:
                path.unlink(missing_ok=True)
        folder.mkdir(parents=True, exist_ok=True)
        stamp.write_text(digest + "\n", encoding="ascii")
    except OSError:
        pass
    return True
