"""Memoisation on disk of deterministic, expensive results shared by several notebooks.

Notebooks 07–09 and their solutions all simulate the same dynamic campaign (same seed, same
sizes); each must still run on its own.  :func:`cached` computes a result once and stores
it under ``build/cache/`` of the output folder (:func:`wsnlib.paths.output_root`), keyed by
the call's name, its arguments and a hash of wsnlib's own source code, so that a changed
simulator or argument never returns a stale result.  A later call with the same key reads the
file instead of computing again; since the computation is deterministic (every random draw
from a seeded generator), the result is the same object either way, bit for bit.

Files are written atomically (a kill leaves no half file) and are plain pickles of wsnlib's
own results: read only what this function wrote.  A file that cannot be read (truncated, empty,
garbage) is named in a warning and computed again.  Delete ``build/cache/`` to start afresh.
"""

from __future__ import annotations

import hashlib
import json
import pickle
from collections.abc import Callable
from pathlib import Path
from typing import Any

import wsnlib
from wsnlib import paths
from wsnlib._files import atomic_write_bytes
from wsnlib._user_warnings import warn_user

#: Bumped when the file layout changes.
CACHE_VERSION = 1


def source_hash() -> str:
    """SHA-256 over wsnlib's ``.py`` files (names and bytes) as this process imported them
    (:data:`wsnlib.SOURCE_DIGEST`, read when the package was imported, not from the files now)."""
    return wsnlib.SOURCE_DIGEST


def cache_dir() -> Path:
    """``build/cache/`` below the output folder, created on first use."""
    folder = paths.output_root() / "build" / "cache"
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def cache_key(name: str, arguments: dict) -> str:
    """Hex key of ``name`` + JSON of ``arguments`` (plain values only) + :func:`source_hash`."""
    if not name.isidentifier():
        raise ValueError(f"name must be an identifier (it names a file), got {name!r}")
    try:
        text = json.dumps(arguments, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"arguments must be plain JSON values (numbers, strings, lists, dicts): {exc}") from exc
    payload = f"{CACHE_VERSION}\n{name}\n{text}\n{source_hash()}"
    return hashlib.sha256(payload.encode()).hexdigest()[:32]


def cached(name: str, arguments: dict, compute: Callable[..., Any]) -> Any:
    """``compute(**arguments)``, read from ``build/cache/`` when it was computed before.

    Parameters
    ----------
    name : str
        What is computed (an identifier; part of the file name).
    arguments : dict
        Keyword arguments of ``compute``, plain JSON values (e.g. a seed, not a generator):
        they and wsnlib's source make the key.
    compute : callable
        Deterministic function of ``arguments``.
    """
    path = cache_dir() / f"{name}-{cache_key(name, arguments)}.pkl"
    if path.exists():
        try:
            with open(path, "rb") as handle:
                return pickle.load(handle)
        except Exception as exc:  # truncated, empty or garbage: any unpickling error
            warn_user(f"{path}: unreadable cache file ({type(exc).__name__}: {exc}); computing {name} again")
    result = compute(**arguments)
    atomic_write_bytes(path, pickle.dumps(result, protocol=pickle.HIGHEST_PROTOCOL))
    return result
