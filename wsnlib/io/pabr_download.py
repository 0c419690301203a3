"""Where the PABR files are, and their verified download (the folder and registry part of
:mod:`wsnlib.io.pabr`, whose docstring documents the dataset and the download rules).

Data credit
-----------
F. S. Daniş, A. T. Naskali, A. T. Cemgil, C. Ersoy, "An Indoor Localization Dataset and Data
Collection Framework with High Precision Position Annotation", *Pervasive and Mobile
Computing* 81, 2022 ("Position Annotated BLE RSSI Dataset for Indoor Localization",
github.com/philotuxo/Position-Annotated-BLE-RSSI-Dataset).  Released under CC0 1.0; cite the
article wherever results from it are shown.

"""

from __future__ import annotations

import logging
import os
import urllib.parse
from pathlib import Path

from wsnlib import paths
from wsnlib.io.download import RegistryEntry, download_verified

logger = logging.getLogger(__name__)

#: Environment variable naming the folder that holds the PABR files.
PABR_DIR_ENV_VAR = "WSNLIB_PABR_DIR"

#: Commit of github.com/philotuxo/Position-Annotated-BLE-RSSI-Dataset the downloads are pinned to.
PABR_COMMIT = "77474b69dc7d73fc5b07b74d7b4b65f3235a663e"

#: Download address of a file of the dataset (``path`` relative to the repository root).
PABR_URL = "https://raw.githubusercontent.com/philotuxo/Position-Annotated-BLE-RSSI-Dataset/{commit}/{path}"


def _read_pabr_registry() -> dict:
    from importlib import resources

    text = resources.files("wsnlib").joinpath("registry", "pabr.tsv").read_text(encoding="utf-8")
    rows = [line.split("\t") for line in text.splitlines() if line and not line.startswith("#")]
    if rows[0] != ["file", "sha256", "bytes"]:
        raise ValueError(f"wsnlib/registry/pabr.tsv: unexpected header {rows[0]}")
    return {name: RegistryEntry(sha256=sha, size_bytes=int(size)) for name, sha, size in rows[1:]}


#: Path (relative to the dataset's root) → expected content (:class:`wsnlib.io.download.RegistryEntry`:
#: SHA-256 and size of the full file at :data:`PABR_COMMIT`) of every file the loaders read:
#: ``LICENSE.md``, ``cnf/tetam.dev``, ``hst/set_1/*``, ``hst/set_2/*``, ``trk/*_all_sensors.mbd``.
PABR_REGISTRY: dict = _read_pabr_registry()


def pabr_dir(data_dir=None) -> Path:
    """Folder of the PABR files: ``data_dir``, else ``$WSNLIB_PABR_DIR``, else ``<ROOT>/data/raw/pabr``."""
    if data_dir is not None:
        return Path(data_dir).expanduser().resolve()
    override = os.environ.get(PABR_DIR_ENV_VAR)
    if override:
        return Path(override).expanduser().resolve()
    return paths.ROOT / "data" / "raw" / "pabr"


def missing_message(path: Path, what: str) -> str:
    """Message of the ``FileNotFoundError`` for a missing PABR file or folder ``path`` (``what`` names it)."""
    return (
        f"PABR {what} not found: {path} is missing (set the folder with the data_dir argument or the "
        f"environment variable {PABR_DIR_ENV_VAR}; default <ROOT>/data/raw/pabr; or call with download=True)"
    )


def require_path(path: Path, what: str, kind: str = "file") -> Path:
    """``path`` if it is an existing file (``kind="folder"``: folder), else ``FileNotFoundError``."""
    ok = path.is_dir() if kind == "folder" else path.is_file()
    if not ok:
        raise FileNotFoundError(missing_message(path, what))
    return path


def pabr_file(relative_path: str, data_dir=None, *, download: bool = True, downloader=None) -> Path:
    """Path of a PABR file, downloading it (verified) if it is missing.

    Parameters
    ----------
    relative_path : str
        A key of :data:`PABR_REGISTRY`, e.g. ``"cnf/tetam.dev"``.
    data_dir : str or pathlib.Path, optional
        Folder; default see :func:`pabr_dir`.
    download : bool
        If False, a missing file raises ``FileNotFoundError``.
    downloader : callable, optional
        Passed on to :func:`pooch.retrieve` (``downloader(url, output_file, pooch)``; default
        pooch's HTTP downloader).

    Returns
    -------
    pathlib.Path
        The file.  A file already present is returned as it is (not hash-checked: the shared
        subset's files are cut versions of the registry's); a downloaded one matched the
        registry's SHA-256.

    Raises
    ------
    ValueError
        Unknown ``relative_path``, or a download whose SHA-256 does not match (nothing is kept).
    FileNotFoundError
        Missing file and ``download`` is False.
    OSError
        The download failed (no network, HTTP error).
    """
    if relative_path not in PABR_REGISTRY:
        raise ValueError(f"unknown PABR file {relative_path!r} (not in wsnlib/registry/pabr.tsv)")
    path = pabr_dir(data_dir) / relative_path
    if not path.is_file():
        if not download:
            raise FileNotFoundError(missing_message(path, f"file {relative_path}"))
        url = PABR_URL.format(commit=PABR_COMMIT, path=urllib.parse.quote(relative_path))
        logger.info("PABR: downloading %s to %s", url, path)
        download_verified(url, path, PABR_REGISTRY[relative_path], downloader, env_var=PABR_DIR_ENV_VAR)
    return path


def registry_files(prefix: str, suffix: str = "") -> list[str]:
    """Registry paths starting with ``prefix`` and ending with ``suffix``, sorted."""
    return sorted(name for name in PABR_REGISTRY if name.startswith(prefix) and name.endswith(suffix))
