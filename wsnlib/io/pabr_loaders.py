"""Parsing of the PABR dataset's files into tables: receivers, fingerprints, tracks (the
loaders of :mod:`wsnlib.io.pabr`, whose docstring documents what they return and how
strictly they parse).

Data credit
-----------
F. S. Daniş, A. T. Naskali, A. T. Cemgil, C. Ersoy, "An Indoor Localization Dataset and Data
Collection Framework with High Precision Position Annotation", *Pervasive and Mobile
Computing* 81, 2022 ("Position Annotated BLE RSSI Dataset for Indoor Localization",
github.com/philotuxo/Position-Annotated-BLE-RSSI-Dataset).  Released under CC0 1.0; cite the
article wherever results from it are shown.

"""

from __future__ import annotations

import io
import json
import logging
import re
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from wsnlib.io.pabr_download import (
    PABR_DIR_ENV_VAR,
    missing_message,
    pabr_dir,
    pabr_file,
    registry_files,
    require_path,
)

logger = logging.getLogger(__name__)

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
            require_path(root, "folder", kind="folder")
        path = pabr_file("cnf/tetam.dev", data_dir, download=download, downloader=downloader)
        pabr_file("LICENSE.md", data_dir, download=download, downloader=downloader)
    text = path.read_text()
    dongles = _parse_dev_line(text, "Dongles", path)
    beacons = _parse_dev_line(text, "Beacons", path)
    rows = []
    for mac, (position, _color, alias) in dongles.items():
        if len(position) != 3:
            raise ValueError(f"{path}: receiver {alias} ({mac}) has position {position}, expected x, y, z")
        rows.append(
            {"receiver": alias, "mac": mac, "x": float(position[0]), "y": float(position[1]), "z": float(position[2])}
        )
    table = pd.DataFrame(rows, columns=["receiver", "mac", "x", "y", "z"])
    if table["receiver"].duplicated().any() or table["mac"].duplicated().any():
        raise ValueError(f"{path}: duplicate receiver alias or MAC")
    table.attrs["beacon"] = [{"mac": mac, "alias": props[2]} for mac, props in beacons.items()][0] if beacons else None
    table.attrs["source"] = str(path)
    return table


def _file_bytes(path: Path) -> tuple[bytes, int]:
    data = path.read_bytes()
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
                raise ValueError(
                    f"{path}, line {number}: {line.count(b',') + 1} comma-separated fields, expected "
                    f"{len(names)} ({', '.join(names[:4])}{', ...' if len(names) > 4 else ''}): {line[:80]!r}"
                )
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


def _drop_invalid(table: pd.DataFrame, what: str) -> pd.DataFrame:
    valid = (table["rssi"] >= RSSI_MIN_DBM) & (table["rssi"] <= RSSI_MAX_DBM)
    n_read, n_dropped = len(table), int((~valid).sum())
    table = table.loc[valid].reset_index(drop=True)
    table.attrs["n_packets_read"] = n_read
    table.attrs["n_dropped_invalid_rssi"] = n_dropped
    logger.info(
        "PABR %s: dropped %d of %d packets with RSSI outside [%g, %g] dBm",
        what,
        n_dropped,
        n_read,
        RSSI_MIN_DBM,
        RSSI_MAX_DBM,
    )
    return table


def _cut_common_span(table: pd.DataFrame, n_packets: int) -> pd.DataFrame:
    """Per point, keep the packets up to the instant one receiver received its ``n_packets``-th."""
    rank = table.groupby(["point", "receiver"], observed=True).cumcount()
    reached = table.loc[rank == n_packets - 1].groupby("point")["timestamp"].min()
    cut = table["point"].map(reached)
    keep = cut.isna() | (table["timestamp"] <= cut)
    return table.loc[keep.to_numpy()].reset_index(drop=True)


def load_pabr_fingerprints(
    set_name: str = "set_1",
    data_dir=None,
    *,
    common_span_packets: int | None = None,
    download: bool = True,
    downloader=None,
) -> pd.DataFrame:
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
        ``n_packets_read`` (after the cut), ``n_dropped_invalid_rssi``, ``source``.

    Raises
    ------
    ValueError
        A malformed file name or line (naming the file and line), a packet of another
        receiver than the file's, or a receiver of ``tetam.dev`` with no file in the set.
    """
    if set_name not in FINGERPRINT_SETS:
        raise ValueError(f"set_name must be one of {FINGERPRINT_SETS}, got {set_name!r}")
    if common_span_packets is not None and (
        isinstance(common_span_packets, bool)
        or not isinstance(common_span_packets, int | np.integer)
        or common_span_packets < 1
    ):
        raise ValueError(f"common_span_packets must be a positive integer or None, got {common_span_packets!r}")
    receivers = load_pabr_receivers(data_dir, download=download, downloader=downloader)
    folder = pabr_dir(data_dir) / "hst" / set_name
    files = sorted(folder.glob("*.mbd"))
    if not files:
        if not download:
            require_path(folder, f"fingerprint folder hst/{set_name}", kind="folder")
            raise FileNotFoundError(
                f"PABR fingerprint folder {folder} holds no .mbd files (set {PABR_DIR_ENV_VAR}, "
                f"or call with download=True)"
            )
        for name in registry_files(f"hst/{set_name}/", ".mbd"):
            pabr_file(name, data_dir, download=True, downloader=downloader)
        files = sorted(folder.glob("*.mbd"))
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
        raise ValueError(
            f"{folder}: no file of receiver(s) {without_file} (expected <sensor>_<x>_<y>_<z>.mbd files for each of "
            f"the {len(mac_of)} receivers of cnf/tetam.dev); is the folder complete?"
        )
    raw = _read_mbd(contents, _HST_FIELDS)
    n_lines = np.array([m[4] for m in meta])
    sensor = np.repeat([m[0] for m in meta], n_lines)
    xyz = np.repeat(np.array([m[1:4] for m in meta]), n_lines, axis=0)
    expected_mac = np.array([mac_of[s] for s in sensor], dtype=object)
    mismatch = raw["mac"].to_numpy(dtype=object) != expected_mac
    if np.any(mismatch):
        row = int(np.argmax(mismatch))
        path, number, _ = _line_of_row(contents, row)
        raise ValueError(
            f"{path}, line {number}: file of {sensor[row]} holds a packet of receiver MAC {raw['mac'][row]}"
        )
    points, point_of_file = np.unique(np.array([m[1:4] for m in meta]), axis=0, return_inverse=True)
    table = pd.DataFrame(
        {
            "point": np.repeat(np.asarray(point_of_file).reshape(-1), n_lines),
            "x": xyz[:, 0],
            "y": xyz[:, 1],
            "z": xyz[:, 2],
            "receiver": pd.Categorical(sensor, categories=list(receivers["receiver"])),
            "timestamp": raw["timestamp"].to_numpy(dtype=float),
            "rssi": raw["rssi"].to_numpy(dtype=float),
        }
    )
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
    folder = pabr_dir(data_dir) / "trk"
    names = sorted(p.name[: -len(_TRACK_SUFFIX)] for p in folder.glob(f"*{_TRACK_SUFFIX}"))
    if not names:
        if not download:
            require_path(folder, "track folder trk", kind="folder")
            raise FileNotFoundError(missing_message(folder / f"*{_TRACK_SUFFIX}", "track files"))
        for name in registry_files("trk/", _TRACK_SUFFIX):
            pabr_file(name, data_dir, download=True, downloader=downloader)
        names = sorted(p.name[: -len(_TRACK_SUFFIX)] for p in folder.glob(f"*{_TRACK_SUFFIX}"))
    return names


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
        ``rssi`` (dBm), ``x``, ``y``, ``z`` (m, ground truth); in file (time) order within each
        track.  ``attrs``: ``n_packets_read``, ``n_dropped_invalid_rssi``, ``source``.
    """
    receivers = load_pabr_receivers(data_dir, download=download, downloader=downloader)
    folder = pabr_dir(data_dir) / "trk"
    if tracks is None:
        names = pabr_track_names(data_dir, download=download, downloader=downloader)
    else:
        names = [tracks] if isinstance(tracks, str) else list(tracks)
        present = {p.name[: -len(_TRACK_SUFFIX)] for p in folder.glob(f"*{_TRACK_SUFFIX}")}
        in_registry = {Path(n).name[: -len(_TRACK_SUFFIX)] for n in registry_files("trk/", _TRACK_SUFFIX)}
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
        raise ValueError(
            f"{path}, line {number}: packet of unknown receiver MAC {raw['mac'][int(np.argmax(unknown_mac))]!r} "
            f"(not in cnf/tetam.dev)"
        )
    table = pd.DataFrame(
        {
            "track": pd.Categorical(np.repeat(names, counts), categories=names),
            "timestamp": raw["timestamp"].to_numpy(dtype=float),
            "receiver": pd.Categorical(raw["mac"].map(alias_of), categories=list(receivers["receiver"])),
            "rssi": raw["rssi"].to_numpy(dtype=float),
            "x": raw["x"].to_numpy(dtype=float),
            "y": raw["y"].to_numpy(dtype=float),
            "z": raw["z"].to_numpy(dtype=float),
        }
    )
    table = _drop_invalid(table, "tracks")
    unheard = [name for name in receivers["receiver"] if name not in set(table["receiver"])]
    if unheard:
        warnings.warn(
            f"PABR tracks {names}: receiver(s) {unheard} of cnf/tetam.dev heard no valid packet; their columns of "
            f"pabr_vectors will be all NaN",
            UserWarning,
            stacklevel=2,
        )
    table.attrs["source"] = str(folder)
    return table
