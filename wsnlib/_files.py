"""Small file utilities shared by the writers, the loaders and the batch runner.

Every file the project writes (CSV, JSON sidecars, the manifest, PNG and PDF figures) goes
through :func:`atomic_path`: it is written to a temporary file in the destination folder and
renamed into place with :func:`os.replace`, so a full disk, an exception or a killed process
leaves the previous file (or none), never half of one.  The temporary files are named
``.<name>.<random>.tmp`` (:func:`is_temporary`); one left behind by a killed process is
harmless and is not reported as an output by :mod:`wsnlib.reproduce`.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import secrets
from collections.abc import Iterator
from pathlib import Path

_TMP_SUFFIX = ".tmp"


def sha256_of(path: Path) -> str:
    """Hex SHA-256 of a file's bytes, read in 1 MiB blocks."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


#: When set (the batch runner sets it per notebook), every file written through
#: :func:`atomic_path` is appended to the file it names, one absolute path per line: how a
#: batch that runs notebooks side by side knows which notebook wrote what.
WRITTEN_LOG_ENV = "WSNLIB_WRITTEN_LOG"


def sources_digest(folder: Path, pattern: str = "*.py") -> str:
    """SHA-256 over the relative names and bytes of the files ``folder.rglob(pattern)``, in name order."""
    folder = Path(folder)
    digest = hashlib.sha256()
    for path in sorted(folder.rglob(pattern)):
        digest.update(path.relative_to(folder).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def _note_written(path: Path) -> None:
    log = os.environ.get(WRITTEN_LOG_ENV)
    if log:
        with open(log, "a", encoding="utf-8") as handle:  # one short line per write: appends do not interleave
            handle.write(f"{Path(path).resolve()}\n")


def is_temporary(path: Path) -> bool:
    """Whether ``path`` is a temporary file of :func:`atomic_path` (``.<name>.<hex>.tmp``)."""
    name = Path(path).name
    return name.startswith(".") and name.endswith(_TMP_SUFFIX)


@contextlib.contextmanager
def atomic_path(path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` when the block succeeds.

    The block writes the complete file to the yielded path (any writer that takes a file
    name: ``fig.savefig``, ``frame.to_csv`` …).  On success the temporary file replaces
    ``path`` in one :func:`os.replace` (atomic on POSIX and Windows when both are in the same
    folder); on any exception it is removed and the exception propagates, leaving ``path`` as
    it was.  Parent folders are created.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(6)}{_TMP_SUFFIX}")
    try:
        yield tmp
        if not tmp.exists():
            raise OSError(f"{path}: nothing was written to the temporary file {tmp.name}")
        os.replace(tmp, path)
        _note_written(path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if str(path) in str(exc):
            raise
        # "[Errno 27] File too large", "[Errno 28] No space left on device" name no file: name it
        message = f"writing {path}: {exc.strerror or exc}"
        raise (OSError(exc.errno, message) if exc.errno is not None else OSError(message)) from exc
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`); return ``path``."""
    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "xb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
    return path


def atomic_write_text(path, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically, encoded with ``encoding`` (no newline translation)."""
    return atomic_write_bytes(path, text.encode(encoding))


def write_csv(frame, path, **to_csv_kwargs) -> Path:
    """``frame.to_csv(path, **to_csv_kwargs)`` through :func:`atomic_path`; return ``path``.

    For processed tables (``wsnlib.paths.data_processed()``): a batch killed while writing
    leaves the previous table or none, never a truncated one.
    """
    path = Path(path)
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, **to_csv_kwargs)
    return path
