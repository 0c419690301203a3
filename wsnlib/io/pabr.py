"""Loader of the PABR dataset (or the project's subset of it): real BLE RSS fingerprints and
tracks (a real-data check of :mod:`wsnlib.radio`).

Data credit
-----------
F. S. Daniş, A. T. Naskali, A. T. Cemgil, C. Ersoy, "An Indoor Localization Dataset and Data
Collection Framework with High Precision Position Annotation", *Pervasive and Mobile
Computing* 81, 2022 ("Position Annotated BLE RSSI Dataset for Indoor Localization",
github.com/philotuxo/Position-Annotated-BLE-RSSI-Dataset).  Released under CC0 1.0; cite the
article wherever results from it are shown.

Folder and download
-------------------
First match wins: the ``data_dir`` argument; else the environment variable
``WSNLIB_PABR_DIR``; else ``<ROOT>/data/raw/pabr/`` (ROOT is :data:`wsnlib.paths.ROOT`).
It holds the dataset's own layout: ``cnf/tetam.dev``, ``hst/set_1/``, ``hst/set_2/``,
``trk/*_all_sensors.mbd``.  What a loader needs and does not find there is downloaded with
pooch from the dataset's repository pinned to commit :data:`PABR_COMMIT`
(``https://raw.githubusercontent.com/philotuxo/Position-Annotated-BLE-RSSI-Dataset/<commit>/<path>``)
into that folder, each file kept only if its SHA-256 matches :data:`PABR_REGISTRY` (shipped as
``wsnlib/registry/pabr.tsv``; the whole dataset part the loaders read is about 266 MB in 1,523
files): the device file (with ``LICENSE.md``) when ``cnf/tetam.dev`` is missing; every file of a
fingerprint set when its folder holds no ``.mbd`` file; a track whose file is missing (all
tracks when ``trk/`` holds none).  Files already there are read as they are, unverified: the
project's shared copy is a documented subset (cut per point, see ``common_span_packets``), not
the registry's full files.  ``download=False`` turns a missing file into ``FileNotFoundError``
naming it and the variable; a failed download is an ``OSError``, a hash mismatch a
``ValueError`` (leaving no file behind).  Tests inject a ``downloader`` (no network).

What the loaders return
-----------------------
* :func:`load_pabr_receivers`: the 12 BLE receivers (our anchors) in the order of
  ``tetam.dev`` — columns ``receiver`` (alias, e.g. ``"sensor10"``), ``mac``, ``x``, ``y``,
  ``z`` (m); the beacon (our target) in ``attrs["beacon"]``.
* :func:`load_pabr_fingerprints` (``"set_1"``: 81 reference points, 2019; ``"set_2"``: 45
  other points, 2020): one row per received packet — ``point`` (int, points numbered in
  order of (x, y, z)), ``x``, ``y``, ``z`` (m, parsed from the file names
  ``<sensor>_<x>_<y>_<z>.mbd``), ``receiver`` (categorical, in receiver order),
  ``timestamp`` (Unix s), ``rssi`` (dBm).  Every receiver of ``tetam.dev`` must have at least
  one file in the set (else ``ValueError`` naming it: a silently missing receiver would turn
  12 anchors into 11).
* :func:`load_pabr_tracks`: one row per packet of the walked trajectories — ``track``
  (categorical, the file name less ``_all_sensors.mbd``), ``timestamp``, ``receiver``,
  ``rssi``, and ``x``, ``y``, ``z``: the AR ground-truth position (m) of the beacon when the
  packet was received (the 3×3 orientation matrix of each line is not kept).  A receiver
  heard in no track is reported by a ``UserWarning``.

Parsing is strict: a line with the wrong number of fields, a field that is not a number, or a
non-finite number (``nan``, ``inf``) raises ``ValueError`` naming the file and the line.
An empty file, a timestamp that is not a Unix time in seconds (milliseconds, say) and a
position that lies far outside the receivers' extent (centimetres, say) raise ``ValueError``
naming the file and the line.  Invalid readings — RSSI above 0 dBm or below −100 dBm
(:data:`RSSI_MIN_DBM`) — are dropped, and so are lines that repeat an earlier one exactly (a
packet stored twice, with a ``UserWarning``).  How many is in ``DataFrame.attrs``
(``n_packets_read``, ``n_dropped_repeated``, ``n_dropped_invalid_rssi``) and logged at INFO level.
The dataset has no missing-value code: a receiver that did not hear
a packet simply has no line.

Online vectors: :func:`pabr_vectors`
------------------------------------
Packets arrive one receiver at a time, so a vector of 12 RSS values must be assembled.
Within each point (fingerprints) or track, either

* ``window_s=w``: consecutive time windows ``[t0 + j·w, t0 + (j+1)·w)``, ``t0`` the group's
  first packet; or
* ``window_packets=n``: per receiver, its packets in time order cut into blocks of ``n``
  (block ``j`` = that receiver's packets ``j·n … j·n + n − 1``; the last incomplete block is
  dropped), so each value averages exactly ``n`` packets.  Use this to study how the error
  depends on the number of packets averaged at a stationary point.  Not for a moving beacon:
  the receivers log independently, so their ``j``-th blocks need not cover the same moment
  (on the tracks of the shared subset, blocks of 30 packets span a median 21 s, in which the
  beacon moves a median 4.8 m; :func:`pabr_vector_motion` measures it): use ``window_s``; or
* ``window="point"`` (fingerprints only): one vector per point, each receiver's mean over
  all its packets there — the classic radio-map fingerprint.

The windowing is :func:`wsnlib.io.vectors.window_readings`, the same function the simulated
path (:func:`wsnlib.io.rss.rss_vectors`) calls, and the result the one vector type,
:class:`wsnlib.io.vectors.RssVectors` (receivers are its ``anchors``).  Vector ``j`` holds,
per receiver, the mean RSS (dBm) of its packets in window/block ``j``, and ``NaN`` where that
receiver had none: a missing reading, which
:mod:`wsnlib.radio` leaves out of training, so a training map is built without ``fill``.  Filling a training
map with a "not heard" level biases it (a receiver that skipped a window is not a very weak
one).  Online vectors must be complete: fill those with ``fill=`` (e.g. ``-100.0``, the
estimators' default ``floor_rss``).  The position of a vector is exact where its group has
one position (a fingerprint point: the position parsed from the file names, so every vector
of a point has the same position and the estimators see one fingerprint per point); else
(tracks) the mean ground-truth position of its packets.  Its time ``time_s`` is the timestamp
of its last packet (when the vector is available; the mean timestamp before issue 13).

Two helpers for the notebook's tests: :func:`pabr_time_split` cuts every point's (or
track's) packets in time (a same-day test: the map from the earlier packets, the test
vectors from the later ones), and :func:`pabr_vector_motion` says how long each vector of a
track spans and how far the beacon moved meanwhile.

Tests that replace the registry patch :data:`PABR_REGISTRY` of this module.
"""

from __future__ import annotations

import io
import json
import logging
import re
import urllib.parse
from pathlib import Path

import numpy as np
import pandas as pd

from wsnlib._user_warnings import warn_user
from wsnlib._validation import check_choice, check_count
from wsnlib.io.download import RegistryEntry, data_folder, download_verified, read_registry
from wsnlib.io.vectors import RssVectors, window_readings

logger = logging.getLogger(__name__)

# --------------------------------------------------------------------------------------
# Folder, registry and verified download
# --------------------------------------------------------------------------------------

#: Environment variable naming the folder that holds the PABR files.
PABR_DIR_ENV_VAR = "WSNLIB_PABR_DIR"

#: Commit of github.com/philotuxo/Position-Annotated-BLE-RSSI-Dataset the downloads are pinned to.
PABR_COMMIT = "77474b69dc7d73fc5b07b74d7b4b65f3235a663e"

#: Download address of a file of the dataset (``path`` relative to the repository root).
PABR_URL = "https://raw.githubusercontent.com/philotuxo/Position-Annotated-BLE-RSSI-Dataset/{commit}/{path}"


#: Path (relative to the dataset's root) → expected content (:class:`wsnlib.io.download.RegistryEntry`:
#: SHA-256 and size of the full file at :data:`PABR_COMMIT`) of every file the loaders read:
#: ``LICENSE.md``, ``cnf/tetam.dev``, ``hst/set_1/*``, ``hst/set_2/*``, ``trk/*_all_sensors.mbd``.
PABR_REGISTRY: dict = {name: RegistryEntry(sha256=sha, size_bytes=int(size))
                       for name, sha, size in read_registry("pabr", ["file", "sha256", "bytes"])}


def pabr_dir(data_dir=None) -> Path:
    """Folder of the PABR files: ``data_dir``, else ``$WSNLIB_PABR_DIR``, else ``<ROOT>/data/raw/pabr``."""
    return data_folder(data_dir, PABR_DIR_ENV_VAR, "pabr")


def _missing_message(path: Path, what: str) -> str:
    """Message of the ``FileNotFoundError`` for a missing PABR file or folder ``path`` (``what`` names it)."""
    return (f"PABR {what} not found: {path} is missing (set the folder with the data_dir argument or the "
            f"environment variable {PABR_DIR_ENV_VAR}; default <ROOT>/data/raw/pabr; or call with download=True)")


def _require_path(path: Path, what: str, kind: str = "file") -> Path:
    """``path`` if it is an existing file (``kind="folder"``: folder), else ``FileNotFoundError``."""
    ok = path.is_dir() if kind == "folder" else path.is_file()
    if not ok:
        raise FileNotFoundError(_missing_message(path, what))
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
            raise FileNotFoundError(_missing_message(path, f"file {relative_path}"))
        url = PABR_URL.format(commit=PABR_COMMIT, path=urllib.parse.quote(relative_path))
        logger.info("PABR: downloading %s to %s", url, path)
        download_verified(url, path, PABR_REGISTRY[relative_path], downloader, env_var=PABR_DIR_ENV_VAR)
    return path


def _registry_files(prefix: str, suffix: str = "") -> list[str]:
    """Registry paths starting with ``prefix`` and ending with ``suffix``, sorted."""
    return sorted(name for name in PABR_REGISTRY if name.startswith(prefix) and name.endswith(suffix))


def _files_of(folder: str, suffix: str, data_dir, download: bool, downloader) -> list[Path]:
    """The files ``*<suffix>`` of the dataset's ``folder`` (e.g. ``"hst/set_1"``), sorted.  If it holds
    none, every such file of the registry is downloaded first (``download=False``: ``FileNotFoundError``)."""
    path = pabr_dir(data_dir) / folder
    files = sorted(path.glob(f"*{suffix}"))
    if not files:
        if not download:
            _require_path(path, f"folder {folder}", kind="folder")
            raise FileNotFoundError(_missing_message(path / f"*{suffix}", f"files of {folder}"))
        for name in _registry_files(f"{folder}/", suffix):
            pabr_file(name, data_dir, download=True, downloader=downloader)
        files = sorted(path.glob(f"*{suffix}"))
    return files

# --------------------------------------------------------------------------------------
# Parsing the files into tables
# --------------------------------------------------------------------------------------


#: Valid RSSI readings lie in ``[RSSI_MIN_DBM, RSSI_MAX_DBM]``; the others are dropped.
RSSI_MIN_DBM = -100.0
RSSI_MAX_DBM = 0.0

#: Packets per file at which the project's shared subset cuts each point (see
#: ``common_span_packets`` of :func:`load_pabr_fingerprints`).
SUBSET_SPAN_PACKETS = 600

FINGERPRINT_SETS = ("set_1", "set_2")

_FINGERPRINT_NAME = re.compile(
    r"^(?P<sensor>[A-Za-z]+\d+)_(?P<x>-?\d+(?:\.\d*)?)_(?P<y>-?\d+(?:\.\d*)?)_(?P<z>-?\d+(?:\.\d*)?)\.mbd$"
)
_TRACK_SUFFIX = "_all_sensors.mbd"
_HST_FIELDS = ["timestamp", "mac", "beacon", "rssi"]
_TRK_FIELDS = ["timestamp", "mac", "beacon", "rssi", "x", "y", "z"] + [f"orientation_{i}" for i in range(9)]
_TEXT_FIELDS = ("mac", "beacon")


def _parse_dev_line(text: str, key: str, path: Path) -> dict:
    for line in text.splitlines():
        if line.startswith(f"{key}:"):
            try:
                return json.loads(line[len(key) + 1 :])
            except json.JSONDecodeError as exc:
                raise ValueError(f"{path}: cannot parse the '{key}:' line ({exc})") from exc
    raise ValueError(f"{path}: no line starting with '{key}:'")


def load_pabr_receivers(data_dir=None, *, download: bool = True, downloader=None) -> pd.DataFrame:
    """The BLE receivers ("dongles", our anchors) of ``cnf/tetam.dev``.

    Parameters
    ----------
    data_dir : path, optional
        The PABR folder (default ``$WSNLIB_PABR_DIR``, else ``<ROOT>/data/raw/pabr``).
    download, downloader
        A missing ``cnf/tetam.dev`` is downloaded (with ``LICENSE.md``); see :func:`pabr_file`.

    Returns
    -------
    DataFrame
        One row per receiver, in file order: ``receiver`` (alias), ``mac``, ``x``, ``y``, ``z``
        (m).  ``attrs["beacon"]`` is ``{"mac": ..., "alias": ...}`` of the (single) beacon.
    """
    root = pabr_dir(data_dir)
    path = root / "cnf" / "tetam.dev"
    if not path.is_file():
        if not download:
            _require_path(root, "folder", kind="folder")
        path = pabr_file("cnf/tetam.dev", data_dir, download=download, downloader=downloader)
        pabr_file("LICENSE.md", data_dir, download=download, downloader=downloader)
    text = path.read_text()
    dongles = _parse_dev_line(text, "Dongles", path)
    beacons = _parse_dev_line(text, "Beacons", path)
    rows = []
    for mac, (position, _color, alias) in dongles.items():
        if len(position) != 3:
            raise ValueError(f"{path}: receiver {alias} ({mac}) has position {position}, expected x, y, z")
        rows.append({"receiver": alias, "mac": mac, "x": float(position[0]), "y": float(position[1]),
                     "z": float(position[2])})
    table = pd.DataFrame(rows, columns=["receiver", "mac", "x", "y", "z"])
    if table["receiver"].duplicated().any() or table["mac"].duplicated().any():
        raise ValueError(f"{path}: duplicate receiver alias or MAC")
    table.attrs["beacon"] = [{"mac": mac, "alias": props[2]} for mac, props in beacons.items()][0] if beacons else None
    table.attrs["source"] = str(path)
    return table


def _file_bytes(path: Path) -> tuple[bytes, int]:
    data = path.read_bytes()
    if not data.strip():
        raise ValueError(f"{path}: the file is empty (every file of the dataset holds packets; an interrupted copy "
                         f"or download?): delete it to download it again")
    if data and not data.endswith(b"\n"):
        data += b"\n"
    return data, sum(1 for line in data.splitlines() if line.strip())


def _line_of_row(files: list[tuple[Path, bytes]], row: int) -> tuple[Path, int, bytes]:
    """File, 1-based line number and text of the ``row``-th non-blank line of the concatenated files."""
    for path, data in files:
        for number, line in enumerate(data.splitlines(), start=1):
            if line.strip():
                if row == 0:
                    return path, number, line
                row -= 1
    raise IndexError(row)


def _read_mbd(files: list[tuple[Path, bytes]], names: list[str]) -> pd.DataFrame:
    """Parse the comma-separated lines of ``files`` (path, bytes) into columns ``names``, strictly.

    Every non-blank line must have ``len(names)`` fields; every field except ``mac`` and
    ``beacon`` must be a finite number.  A violation raises ``ValueError`` naming the file and
    the line.
    """
    data = b"".join(chunk for _, chunk in files)
    n_rows = sum(1 for line in data.splitlines() if line.strip())
    if n_rows == 0:
        return pd.DataFrame({name: pd.Series(dtype=str if name in _TEXT_FIELDS else float) for name in names})
    if data.count(b",") != (len(names) - 1) * n_rows:
        for row in range(n_rows):
            path, number, line = _line_of_row(files, row)
            if line.count(b",") != len(names) - 1:
                raise ValueError(f"{path}, line {number}: {line.count(b',') + 1} comma-separated fields, expected "
                                 f"{len(names)} ({', '.join(names[:4])}{', ...' if len(names) > 4 else ''}): "
                                 f"{line[:80]!r}")
    try:
        # No NA parsing: a column with "nan", an empty or a non-numeric field stays text, found below.
        text = pd.read_csv(io.BytesIO(data), header=None, names=names, dtype=dict.fromkeys(_TEXT_FIELDS, str),
                           na_filter=False, index_col=False)
    except pd.errors.ParserError as exc:  # not expected after the field count check
        raise ValueError(f"{', '.join(str(p) for p, _ in files[:3])}: malformed lines ({exc})") from exc
    if len(text) != n_rows:
        raise ValueError(f"{files[0][0].parent}: read {len(text)} rows, expected {n_rows} (malformed lines)")
    table = pd.DataFrame(index=text.index)
    for name in names:
        if name in _TEXT_FIELDS:
            table[name] = text[name]
            continue
        column = text[name]
        if pd.api.types.is_numeric_dtype(column):
            values = column.to_numpy(dtype=float)
        else:
            values = pd.to_numeric(column.astype(str), errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(values)
        if np.any(bad):
            row = int(np.argmax(bad))
            path, number, _ = _line_of_row(files, row)
            raw = str(text[name].iloc[row]).strip()
            if raw.lower().lstrip("+-") in ("nan", "inf", "infinity"):
                problem = f"{name} is {raw} (not a finite number; the dataset has no missing-value code)"
            else:
                problem = f"{name} is {raw!r}, not a number"
            raise ValueError(f"{path}, line {number}: {problem}")
        table[name] = values
    return table


#: Above this a timestamp cannot be Unix seconds (year 5138): the dataset's are ~1.6e9 s, in ms ~1.6e12.
_LARGEST_UNIX_S = 1e11


def _check_units(table: pd.DataFrame, receivers: pd.DataFrame, files: list[tuple[Path, bytes]], what: str) -> None:
    """``ValueError`` naming the file and line of a timestamp in milliseconds or a position not in metres.

    ``table``'s rows are in the order of ``files``' lines.  A position may lie outside the receivers'
    bounding box of ``cnf/tetam.dev`` (the dataset's points reach 2.4 m out), but not by more than the
    box's diagonal (at least 5 m): positions in centimetres would put it hundreds of metres out.
    """
    time_s = table["timestamp"].to_numpy()
    if np.any(time_s > _LARGEST_UNIX_S):
        row = int(np.argmax(time_s > _LARGEST_UNIX_S))
        path, number, _ = _line_of_row(files, row)
        raise ValueError(f"{path}, line {number}: timestamp {time_s[row]:.6g} is not a Unix time in seconds "
                         f"(above {_LARGEST_UNIX_S:.0e}; milliseconds?)")
    box = receivers[["x", "y", "z"]].to_numpy()
    low, high = box.min(axis=0), box.max(axis=0)
    xyz = table[["x", "y", "z"]].to_numpy()
    outside = np.linalg.norm(xyz - np.clip(xyz, low, high), axis=1)
    bad = outside > max(5.0, float(np.linalg.norm(high - low)))
    if np.any(bad):
        row = int(np.argmax(bad))
        path, number, _ = _line_of_row(files, row)
        raise ValueError(f"{path}, line {number}: {what} position {xyz[row].tolist()} lies {outside[row]:.1f} m "
                         f"outside the receivers' extent in cnf/tetam.dev (positions must be in metres, not cm)")


def _drop_invalid(table: pd.DataFrame, what: str) -> pd.DataFrame:
    """Drop repeated packets (identical rows; one ``UserWarning``) and RSSI outside the valid range; count both."""
    repeated = table.duplicated().to_numpy()
    valid = ((table["rssi"] >= RSSI_MIN_DBM) & (table["rssi"] <= RSSI_MAX_DBM)).to_numpy()
    n_read, n_repeated, n_dropped = len(table), int(repeated.sum()), int((~valid & ~repeated).sum())
    table = table.loc[valid & ~repeated].reset_index(drop=True)
    table.attrs.update(n_packets_read=n_read, n_dropped_repeated=n_repeated, n_dropped_invalid_rssi=n_dropped)
    if n_repeated:
        warn_user(f"PABR {what}: dropped {n_repeated} of {n_read} packets that repeat an earlier line exactly "
                  f"(the same packet stored twice)")
    logger.info("PABR %s: dropped %d of %d packets with RSSI outside [%g, %g] dBm", what, n_dropped, n_read,
                RSSI_MIN_DBM, RSSI_MAX_DBM)
    return table


def _cut_common_span(table: pd.DataFrame, n_packets: int) -> pd.DataFrame:
    """Per point, keep the packets up to the instant one receiver received its ``n_packets``-th."""
    rank = table.groupby(["point", "receiver"], observed=True).cumcount()
    reached = table.loc[rank == n_packets - 1].groupby("point")["timestamp"].min()
    cut = table["point"].map(reached)
    keep = cut.isna() | (table["timestamp"] <= cut)
    return table.loc[keep.to_numpy()].reset_index(drop=True)


def load_pabr_fingerprints(set_name: str = "set_1", data_dir=None, *, common_span_packets: int | None = None,
                           download: bool = True, downloader=None) -> pd.DataFrame:
    """Packets recorded at the stationary reference points of ``hst/<set_name>/``.

    Parameters
    ----------
    set_name : {"set_1", "set_2"}
    data_dir : path, optional
        The PABR folder (default ``$WSNLIB_PABR_DIR``, else ``<ROOT>/data/raw/pabr``).
    common_span_packets : int, optional
        Cut every point to one common time span: keep, for every receiver, its packets up to
        the instant at which the first receiver of that point received its
        ``common_span_packets``-th packet (inclusive; counted in time order, before invalid
        readings are dropped).  :data:`SUBSET_SPAN_PACKETS` (600) reproduces the project's
        shared subset from the full files, and leaves that subset unchanged.  Default: no cut.
    download, downloader
        If the set's folder holds no ``.mbd`` file, every file of the set is downloaded
        (verified); see :func:`pabr_file`.

    Returns
    -------
    DataFrame
        Columns ``point`` (int, numbered in order of (x, y, z)), ``x``, ``y``, ``z`` (m),
        ``receiver`` (categorical, receiver order), ``timestamp`` (s), ``rssi`` (dBm); sorted
        by point, receiver, timestamp.  ``attrs``: ``set_name``, ``n_points``,
        ``n_packets_read`` (after the cut), ``n_dropped_repeated``, ``n_dropped_invalid_rssi``,
        ``source``.

    Raises
    ------
    ValueError
        A malformed file name or line (naming the file and line), a packet of another
        receiver than the file's, or a receiver of ``tetam.dev`` with no file in the set.
    """
    check_choice(set_name, "set_name", FINGERPRINT_SETS)
    if common_span_packets is not None:
        check_count(common_span_packets, "common_span_packets")
    receivers = load_pabr_receivers(data_dir, download=download, downloader=downloader)
    folder = pabr_dir(data_dir) / "hst" / set_name
    files = _files_of(f"hst/{set_name}", ".mbd", data_dir, download, downloader)
    mac_of = dict(zip(receivers["receiver"], receivers["mac"], strict=True))
    contents, meta = [], []
    for path in files:
        match = _FINGERPRINT_NAME.match(path.name)
        if match is None:
            raise ValueError(f"{path}: file name does not follow <sensor>_<x>_<y>_<z>.mbd")
        sensor = match["sensor"]
        if sensor not in mac_of:
            raise ValueError(f"{path}: unknown receiver {sensor!r}; known: {list(mac_of)}")
        data, n_lines = _file_bytes(path)
        contents.append((path, data))
        meta.append((sensor, float(match["x"]), float(match["y"]), float(match["z"]), n_lines))
    without_file = [name for name in mac_of if name not in {m[0] for m in meta}]
    if without_file:
        raise ValueError(f"{folder}: no file of receiver(s) {without_file} (expected <sensor>_<x>_<y>_<z>.mbd files "
                         f"for each of the {len(mac_of)} receivers of cnf/tetam.dev); is the folder complete?")
    raw = _read_mbd(contents, _HST_FIELDS)
    n_lines = np.array([m[4] for m in meta])
    sensor = np.repeat([m[0] for m in meta], n_lines)
    xyz = np.repeat(np.array([m[1:4] for m in meta]), n_lines, axis=0)
    expected_mac = np.array([mac_of[s] for s in sensor], dtype=object)
    mismatch = raw["mac"].to_numpy(dtype=object) != expected_mac
    if np.any(mismatch):
        row = int(np.argmax(mismatch))
        path, number, _ = _line_of_row(contents, row)
        raise ValueError(f"{path}, line {number}: file of {sensor[row]} holds a packet of receiver MAC "
                         f"{raw['mac'][row]}")
    points, point_of_file = np.unique(np.array([m[1:4] for m in meta]), axis=0, return_inverse=True)
    table = pd.DataFrame({"point": np.repeat(np.asarray(point_of_file).reshape(-1), n_lines), "x": xyz[:, 0],
                          "y": xyz[:, 1], "z": xyz[:, 2],
                          "receiver": pd.Categorical(sensor, categories=list(receivers["receiver"])),
                          "timestamp": raw["timestamp"].to_numpy(dtype=float),
                          "rssi": raw["rssi"].to_numpy(dtype=float)})
    _check_units(table, receivers, contents, "reference point")
    table = table.sort_values(["point", "receiver", "timestamp"], kind="stable").reset_index(drop=True)
    if common_span_packets is not None:
        table = _cut_common_span(table, int(common_span_packets))
    table = _drop_invalid(table, f"fingerprints {set_name}")
    table.attrs.update({"set_name": set_name, "n_points": len(points), "source": str(folder)})
    return table


def pabr_track_names(data_dir=None, *, download: bool = True, downloader=None) -> list[str]:
    """Names of the tracks (file names less ``_all_sensors.mbd``), sorted.

    Those in ``trk/``; if it holds none, every track of the registry is downloaded first
    (unless ``download=False``, which raises ``FileNotFoundError``).
    """
    files = _files_of("trk", _TRACK_SUFFIX, data_dir, download, downloader)
    return sorted(p.name[: -len(_TRACK_SUFFIX)] for p in files)


def load_pabr_tracks(tracks=None, data_dir=None, *, download: bool = True, downloader=None) -> pd.DataFrame:
    """Packets of the walked trajectories ``trk/<track>_all_sensors.mbd`` with ground truth.

    Parameters
    ----------
    tracks : str or list of str, optional
        Track names (see :func:`pabr_track_names`); default all in the folder.  A track of the
        registry missing from the folder is downloaded (unless ``download=False``).
    data_dir : path, optional
        The PABR folder.
    download, downloader
        See :func:`pabr_file`.

    Returns
    -------
    DataFrame
        Columns ``track`` (categorical), ``timestamp`` (s), ``receiver`` (categorical),
        ``rssi`` (dBm), ``x``, ``y``, ``z`` (m, ground truth); in time order within each track
        (stable: the files' order where timestamps tie).  ``attrs``: ``n_packets_read``,
        ``n_dropped_repeated``, ``n_dropped_invalid_rssi``, ``source``.
    """
    receivers = load_pabr_receivers(data_dir, download=download, downloader=downloader)
    folder = pabr_dir(data_dir) / "trk"
    if tracks is None:
        names = pabr_track_names(data_dir, download=download, downloader=downloader)
    else:
        names = [tracks] if isinstance(tracks, str) else list(tracks)
        present = {p.name[: -len(_TRACK_SUFFIX)] for p in folder.glob(f"*{_TRACK_SUFFIX}")}
        in_registry = {Path(n).name[: -len(_TRACK_SUFFIX)] for n in _registry_files("trk/", _TRACK_SUFFIX)}
        unknown = [n for n in names if n not in present and n not in in_registry]
        if unknown:
            raise ValueError(f"unknown PABR track(s) {unknown}; known tracks: {sorted(present | in_registry)}")
    if not names:
        raise ValueError("tracks must name at least one track")
    alias_of = dict(zip(receivers["mac"], receivers["receiver"], strict=True))
    contents, counts = [], []
    for name in names:
        path = folder / f"{name}{_TRACK_SUFFIX}"
        if not path.is_file():
            path = pabr_file(f"trk/{name}{_TRACK_SUFFIX}", data_dir, download=download, downloader=downloader)
        data, n_lines = _file_bytes(path)
        contents.append((path, data))
        counts.append(n_lines)
    raw = _read_mbd(contents, _TRK_FIELDS)
    unknown_mac = ~raw["mac"].isin(list(alias_of)).to_numpy()
    if np.any(unknown_mac):
        path, number, _ = _line_of_row(contents, int(np.argmax(unknown_mac)))
        raise ValueError(f"{path}, line {number}: packet of unknown receiver MAC "
                         f"{raw['mac'][int(np.argmax(unknown_mac))]!r} (not in cnf/tetam.dev)")
    table = pd.DataFrame({"track": pd.Categorical(np.repeat(names, counts), categories=names),
                          "timestamp": raw["timestamp"].to_numpy(dtype=float),
                          "receiver": pd.Categorical(raw["mac"].map(alias_of), categories=list(receivers["receiver"])),
                          **{c: raw[c].to_numpy(dtype=float) for c in ("rssi", "x", "y", "z")}})
    _check_units(table, receivers, contents, "ground-truth")
    # receive order is not always time order (sub-millisecond swaps in the dataset's own files)
    table = table.sort_values(["track", "timestamp"], kind="stable").reset_index(drop=True)
    table = _drop_invalid(table, "tracks")
    unheard = [name for name in receivers["receiver"] if name not in set(table["receiver"])]
    if unheard:
        warn_user(f"PABR tracks {names}: receiver(s) {unheard} of cnf/tetam.dev heard no valid packet; their "
                  f"columns of pabr_vectors will be all NaN")
    table.attrs["source"] = str(folder)
    return table

# --------------------------------------------------------------------------------------
# RSS vectors
# --------------------------------------------------------------------------------------


#: Names that :func:`pabr_vectors` gives the fields the dataset has no column for.
PABR_USER = "PABR"
PABR_TARGET = "beacon"


def pabr_vectors(table: pd.DataFrame, *, window_s: float | None = None, window_packets: int | None = None,
                 window: str | None = None, fill: str | float | None = None, floor_dbm: float = RSSI_MIN_DBM,
                 min_receivers: int = 1, group: str | None = None) -> RssVectors:
    """RSS vectors (one value per receiver) from a long table of packets; see the module docstring.

    A thin wrapper of :func:`wsnlib.io.vectors.window_readings` (the windowing the simulated
    path shares): each point (fingerprints) or track is one point of the readings, so a
    window never mixes two; receivers are the vectors' anchors.

    Parameters
    ----------
    table : DataFrame
        From :func:`load_pabr_fingerprints` or :func:`load_pabr_tracks` (columns ``timestamp``,
        ``receiver``, ``rssi``, ``x``, ``y``, ``z`` and the group column).
    window_s : float, optional
        Length (s) of the time windows.
    window_packets : int, optional
        Packets per receiver averaged into each value (blocks of consecutive packets; an
        incomplete last block is dropped).
    window : {"point"}, optional
        ``"point"``: one vector per point (group ``"point"`` only), each receiver's mean over
        all its packets there.  Exactly one of ``window_s``, ``window_packets`` and ``window``.
    fill : None, "last", "floor" or float
        What replaces a missing reading (:mod:`wsnlib.io.vectors`); default keep NaN.  For
        online vectors only, e.g. ``fill=-100.0``: a training map keeps NaN, which the
        estimators of :mod:`wsnlib.radio` leave out of the cell's mean.
    floor_dbm : float
        The "not heard" level of ``fill="last"`` / ``"floor"`` (default −100 dBm,
        :data:`RSSI_MIN_DBM`).
    min_receivers : int
        Drop vectors heard by fewer receivers than this (default 1: keep all).
    group : str, optional
        Column whose values are never mixed in a window; default ``"point"`` if present, else
        ``"track"``.

    Returns
    -------
    RssVectors
        Ordered by group, then window.  ``label`` is the point number or
        track name, ``session`` the same as text, ``user`` :data:`PABR_USER`, ``target``
        :data:`PABR_TARGET`.  A point's vectors all have its exact position.
    """
    if sum(arg is not None for arg in (window_s, window_packets, window)) != 1:
        raise ValueError("give exactly one of window_s (seconds), window_packets (packets per receiver) and "
                         "window='point'")
    if group is None:
        group = "point" if "point" in table.columns else "track"
    if window is not None and (window != "point" or group != "point"):
        raise ValueError(f"window must be 'point' (one vector per fingerprint point, group 'point'), got {window!r}"
                         f" with group {group!r}")
    needed = [group, "timestamp", "receiver", "rssi", "x", "y", "z"]
    missing = [c for c in needed if c not in table.columns]
    if missing:
        raise ValueError(f"table lacks the column(s) {missing} (expected a load_pabr_* table)")
    check_count(min_receivers, "min_receivers")
    receiver = table["receiver"]
    categorical = isinstance(receiver.dtype, pd.CategoricalDtype)
    names = list(receiver.cat.categories) if categorical else sorted(receiver.unique())
    df = table[needed].copy()
    df["receiver"] = pd.Categorical(df["receiver"], categories=names)
    df = df.sort_values([group, "receiver", "timestamp"], kind="stable")
    label = df[group].to_numpy(dtype=object)
    readings = pd.DataFrame({
        "user": PABR_USER, "session": label.astype(str), "target": PABR_TARGET, "label": label,
        "anchor": df["receiver"].astype(object).to_numpy(), "rss_dbm": df["rssi"].to_numpy(dtype=float),
        "time_s": df["timestamp"].to_numpy(dtype=float), "x_m": df["x"].to_numpy(dtype=float),
        "y_m": df["y"].to_numpy(dtype=float), "z_m": df["z"].to_numpy(dtype=float)})
    return window_readings(readings, tuple(names), window_packets=window_packets, window_s=window_s, window=window,
                           complete_windows=True, fill=fill, floor_dbm=floor_dbm, min_anchors=min_receivers)


def _group_column(table: pd.DataFrame, group: str | None) -> str:
    group = ("point" if "point" in table.columns else "track") if group is None else group
    if group not in table.columns or "timestamp" not in table.columns:
        raise ValueError(f"table lacks the column(s) {[c for c in (group, 'timestamp') if c not in table.columns]} "
                         "(expected a load_pabr_* table)")
    return group


def pabr_time_split(table: pd.DataFrame, fraction: float = 0.5, *,
                    group: str | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Every point's (or track's) packets cut in time: ``(earlier, later)``.

    Within each group the cut is at ``t0 + fraction · (t1 − t0)``, ``t0`` and ``t1`` its first
    and last packet: packets before the cut go to ``earlier``, the others to ``later``.  A
    same-day test: the radio map from the earlier packets, the online vectors from the later
    ones, at the same points.

    Parameters
    ----------
    table : DataFrame
        From :func:`load_pabr_fingerprints` or :func:`load_pabr_tracks`.
    fraction : float
        Share of each group's time span that goes to ``earlier``, in (0, 1).
    group : str, optional
        Default ``"point"`` if present, else ``"track"``.

    Returns
    -------
    tuple of DataFrame
        The rows of ``table`` in their order (index reset), ``attrs`` kept.
    """
    fraction = float(fraction)
    if not 0.0 < fraction < 1.0:
        raise ValueError(f"fraction must lie strictly between 0 and 1, got {fraction!r}")
    group = _group_column(table, group)
    times = table.groupby(group, observed=True)["timestamp"]
    start, end = times.transform("min"), times.transform("max")
    earlier = (table["timestamp"] < start + fraction * (end - start)).to_numpy()
    parts = []
    for keep in (earlier, ~earlier):
        part = table.loc[keep].reset_index(drop=True)
        part.attrs = dict(table.attrs)
        parts.append(part)
    return parts[0], parts[1]


def pabr_vector_motion(tracks: pd.DataFrame, vectors: RssVectors) -> pd.DataFrame:
    """How long each vector of a track spans, and how far the beacon moved meanwhile.

    Parameters
    ----------
    tracks : DataFrame
        From :func:`load_pabr_tracks` (the ground truth ``x``, ``y``, ``z`` of every packet).
    vectors : RssVectors
        :func:`pabr_vectors` of ``tracks`` (``label`` = the track).

    Returns
    -------
    DataFrame
        One row per vector: ``span_s`` (s), from its first to its last reading
        (``time_s − first_time_s``), and ``moved_m`` (m), the distance between the beacon's
        ground-truth positions at those two instants (linear between the packets' positions).
    """
    if "track" not in tracks.columns:
        raise ValueError("tracks must be a load_pabr_tracks table (a 'track' column)")
    moved = np.full(len(vectors), np.nan)
    labels = np.asarray(vectors.label).astype(str)
    for name, packets in tracks.groupby("track", observed=True):
        rows = labels == str(name)
        if not rows.any():
            continue
        packets = packets.sort_values("timestamp", kind="stable")
        time = packets["timestamp"].to_numpy()
        at = [np.column_stack([np.interp(t, time, packets[c].to_numpy()) for c in ("x", "y", "z")])
              for t in (vectors.first_time_s[rows], vectors.time_s[rows])]
        moved[rows] = np.linalg.norm(at[1] - at[0], axis=1)
    if np.isnan(moved).any():
        missing = sorted(set(labels[np.isnan(moved)]))
        raise ValueError(f"vectors of track(s) {missing} not in tracks")
    return pd.DataFrame({"span_s": vectors.time_s - vectors.first_time_s, "moved_m": moved})
