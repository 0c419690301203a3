"""Verified downloads of dataset files, shared by the BROAD (:mod:`wsnlib.io.broad`) and PABR
(:mod:`wsnlib.io.pabr`) loaders.

A registry (shipped under ``wsnlib/registry/``, read by :func:`read_registry`) maps each file
of a dataset to its expected content (:class:`RegistryEntry`); :func:`download_verified`
fetches a file with pooch and keeps it only if it matches: its SHA-256, or where the registry
has none its git blob id (:func:`git_blob_sha1_of`).  :func:`data_folder` is where a dataset's
files live.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

from wsnlib import paths


@dataclass(frozen=True)
class RegistryEntry:
    """Expected content of one file of a dataset registry.

    Attributes
    ----------
    sha256 : str or None
        Hex SHA-256 of the file; None where the registry does not know it.
    git_blob_sha1 : str or None
        Git's blob id of the file: hex SHA-1 of ``b"blob <size>\\0"`` followed by the content
        (see :func:`git_blob_sha1_of`); used when ``sha256`` is None.
    size_bytes : int or None
        Size of the file (bytes), where the registry gives it (informative).
    """

    sha256: str | None
    git_blob_sha1: str | None = None
    size_bytes: int | None = None


def data_folder(data_dir, env_var: str, name: str) -> Path:
    """A dataset's folder: ``data_dir``, else ``$<env_var>``, else ``<ROOT>/data/raw/<name>`` (not created here).

    Raises ``NotADirectoryError`` naming the argument or the variable when it names an existing file.
    """
    override = os.environ.get(env_var)
    if data_dir is not None:
        folder, source = Path(data_dir).expanduser().resolve(), "data_dir"
    elif override:
        folder, source = Path(override).expanduser().resolve(), f"${env_var}"
    else:
        return paths.ROOT / "data" / "raw" / name
    if folder.is_file():
        raise NotADirectoryError(f"{source} must name the {name} folder, but {folder} is a file")
    return folder


def read_registry(name: str, header: list[str]) -> list[list[str]]:
    """The rows (tab-separated fields) of the shipped ``wsnlib/registry/<name>.tsv`` below its ``header``."""
    from importlib import resources

    text = resources.files("wsnlib").joinpath("registry", f"{name}.tsv").read_text(encoding="utf-8")
    rows = [(number, line.split("\t")) for number, line in enumerate(text.splitlines(), start=1)
            if line and not line.startswith("#")]
    if not rows or rows[0][1] != header:
        found = rows[0][1] if rows else None
        raise ValueError(f"wsnlib/registry/{name}.tsv: expected the header {header}, got {found}")
    for number, fields in rows[1:]:
        if len(fields) != len(header):
            raise ValueError(f"wsnlib/registry/{name}.tsv, line {number}: {len(fields)} tab-separated fields, "
                             f"expected {len(header)} ({', '.join(header)})")
    return [fields for _, fields in rows[1:]]


def git_blob_sha1_of(path: Path) -> str:
    """Git's blob id of a file: hex SHA-1 of ``b"blob <size in bytes>\\0"`` followed by its bytes."""

    path = Path(path)
    digest = hashlib.sha1(f"blob {path.stat().st_size}\0".encode("ascii"))
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def download_verified(url: str, path: Path, expected: RegistryEntry, downloader, *, env_var: str) -> None:
    """Download ``url`` to ``path`` with pooch, keeping it only if it matches ``expected``.

    ``downloader`` is passed on to :func:`pooch.retrieve` (None: pooch's HTTP downloader);
    ``env_var`` names the folder variable the error message suggests.

    With a SHA-256, pooch checks it (writing to a temporary file in the same folder and moving
    it into place only on a match).  With only a git blob id, the file is downloaded under a
    temporary name, checked here, then renamed into place (``os.replace``) or deleted.  A failed
    download also removes the folders it created, if they are still empty.
    """
    import pooch

    created = [folder for folder in (path.parent, *path.parent.parents) if not folder.exists()]  # deepest first
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f".{path.name}.download")
    done = False
    try:
        if expected.sha256 is not None:
            pooch.retrieve(url, known_hash=f"sha256:{expected.sha256}", fname=path.name, path=path.parent,
                           downloader=downloader, progressbar=False)
        else:
            partial.unlink(missing_ok=True)
            pooch.retrieve(url, known_hash=None, fname=partial.name, path=path.parent,
                           downloader=downloader, progressbar=False)
            actual = git_blob_sha1_of(partial)
            if actual != expected.git_blob_sha1:
                raise ValueError(f"git blob id of the download is {actual}, expected {expected.git_blob_sha1}")
            os.replace(partial, path)
        done = True
    except ValueError as exc:
        wanted = f"SHA-256 {expected.sha256}" if expected.sha256 else f"git blob id {expected.git_blob_sha1}"
        raise ValueError(f"download of {path.name} from {url} failed the hash check (expected {wanted}); "
                         f"nothing was written to {path}. Details: {exc}") from exc
    except OSError as exc:
        raise OSError(f"could not download {url} to {path}: {exc}. Without network, copy the file there "
                      f"by hand or set ${env_var} to a folder holding it") from exc
    finally:
        partial.unlink(missing_ok=True)
        if not done:
            for folder in created:
                try:
                    folder.rmdir()  # only if empty: another file may have arrived meanwhile
                except OSError:
                    break
