"""Loader of the PABR subset: real BLE RSS fingerprints and tracks (a real-data check of
:mod:`wsnlib.fingerprint`).

Data credit
-----------
F. S. Daniş, A. T. Naskali, A. T. Cemgil, C. Ersoy, "An Indoor Localization Dataset and Data
Collection Framework with High Precision Position Annotation", *Pervasive and Mobile
Computing* 81, 2022 ("Position Annotated BLE RSSI Dataset for Indoor Localization",
github.com/philotuxo/Position-Annotated-BLE-RSSI-Dataset).  Released under CC0 1.0; cite the
article wherever results from it are shown.

Folder
------
First match wins: the ``data_dir`` argument; else the environment variable
``WSNLIB_PABR_DIR``; else ``<ROOT>/data/raw/pabr/`` (ROOT is :data:`wsnlib.paths.ROOT`).
It holds the dataset's own layout: ``cnf/tetam.dev``, ``hst/set_1/``, ``hst/set_2/``,
``trk/*_all_sensors.mbd``.  A missing folder or file raises ``FileNotFoundError`` naming it
and the variable.  Nothing is downloaded.

What the loaders return
-----------------------
* :func:`load_pabr_receivers`: the 12 BLE receivers (our anchors) in the order of
  ``tetam.dev`` — columns ``receiver`` (alias, e.g. ``"sensor10"``), ``mac``, ``x``, ``y``,
  ``z`` (m); the beacon (our target) in ``attrs["beacon"]``.
* :func:`load_pabr_fingerprints` (``"set_1"``: 81 reference points, 2019; ``"set_2"``: 45
  other points, 2020): one row per received packet — ``point`` (int, points numbered in
  order of (x, y, z)), ``x``, ``y``, ``z`` (m, parsed from the file names
  ``<sensor>_<x>_<y>_<z>.mbd``), ``receiver`` (categorical, in receiver order),
  ``timestamp`` (Unix s), ``rssi`` (dBm).
* :func:`load_pabr_tracks`: one row per packet of the walked trajectories — ``track``
  (categorical, the file name less ``_all_sensors.mbd``), ``timestamp``, ``receiver``,
  ``rssi``, and ``x``, ``y``, ``z``: the AR ground-truth position (m) of the beacon when the
  packet was received (the 3×3 orientation matrix of each line is not kept).

Invalid readings — RSSI above 0 dBm or below −100 dBm (:data:`RSSI_MIN_DBM`) — are dropped.
How many is in ``DataFrame.attrs`` (``n_packets_read``, ``n_dropped_invalid_rssi``) and
logged at INFO level.  The dataset has no missing-value code: a receiver that did not hear
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
  depends on the number of packets averaged; for a moving beacon prefer ``window_s``, since
  the receivers' ``j``-th blocks need not cover the same moment.

Vector ``j`` holds, per receiver, the mean RSS (dBm) of its packets in window/block ``j``,
and ``NaN`` where that receiver had none (a missing reading, which
:mod:`wsnlib.fingerprint` leaves out of training).  For online use fill those with
``fill=`` (e.g. ``-100.0``, the "not heard" level that is also the estimators' default
``floor_rss``).  The position of a vector is the mean position of its packets (the point for
fingerprints; the mean ground truth for tracks), its time the mean timestamp of its packets.
"""

from __future__ import annotations

import dataclasses
import io
import json
import logging
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from . import paths

logger = logging.getLogger(__name__)

#: Environment variable naming the folder that holds the PABR subset.
PABR_DIR_ENV_VAR = "WSNLIB_PABR_DIR"

#: Valid RSSI readings lie in ``[RSSI_MIN_DBM, RSSI_MAX_DBM]``; the others are dropped.
RSSI_MIN_DBM = -100.0
RSSI_MAX_DBM = 0.0

FINGERPRINT_SETS = ("set_1", "set_2")

_FINGERPRINT_NAME = re.compile(
    r"^(?P<sensor>[A-Za-z]+\d+)_(?P<x>-?\d+(?:\.\d*)?)_(?P<y>-?\d+(?:\.\d*)?)_(?P<z>-?\d+(?:\.\d*)?)\.mbd$"
)
_TRACK_SUFFIX = "_all_sensors.mbd"
_TRACK_FIELDS = 16  # timestamp, sensor MAC, beacon MAC, rssi, x, y, z, 3x3 orientation


def pabr_dir(data_dir=None) -> Path:
    """Folder of the PABR subset: ``data_dir``, else ``$WSNLIB_PABR_DIR``, else ``<ROOT>/data/raw/pabr``."""
    if data_dir is not None:
        return Path(data_dir).expanduser().resolve()
    override = os.environ.get(PABR_DIR_ENV_VAR)
    if override:
        return Path(override).expanduser().resolve()
    return paths.ROOT / "data" / "raw" / "pabr"


def _require(path: Path, what: str, kind: str = "file") -> Path:
    ok = path.is_dir() if kind == "folder" else path.is_file()
    if not ok:
        raise FileNotFoundError(
            f"PABR {what} not found: {path} is missing (set the folder with the data_dir argument or the "
            f"environment variable {PABR_DIR_ENV_VAR}; default <ROOT>/data/raw/pabr)"
        )
    return path


def _root(data_dir) -> Path:
    return _require(pabr_dir(data_dir), "folder", kind="folder")


def _parse_dev_line(text: str, key: str, path: Path) -> dict:
    for line in text.splitlines():
        if line.startswith(f"{key}:"):
            try:
                return json.loads(line[len(key) + 1 :])
            except json.JSONDecodeError as exc:
                raise ValueError(f"{path}: cannot parse the '{key}:' line ({exc})") from exc
    raise ValueError(f"{path}: no line starting with '{key}:'")


def load_pabr_receivers(data_dir=None) -> pd.DataFrame:
    """The BLE receivers ("dongles", our anchors) of ``cnf/tetam.dev``.

    Returns
    -------
    DataFrame
        One row per receiver, in file order: ``receiver`` (alias), ``mac``, ``x``, ``y``, ``z``
        (m).  ``attrs["beacon"]`` is ``{"mac": ..., "alias": ...}`` of the (single) beacon.
    """
    path = _require(_root(data_dir) / "cnf" / "tetam.dev", "device file cnf/tetam.dev")
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


def _read_mbd(chunks: list[bytes], names: list[str], n_fields: int, what: str) -> pd.DataFrame:
    data = b"".join(chunks)
    if not data.strip():
        return pd.DataFrame({name: pd.Series(dtype=float) for name in names})
    table = pd.read_csv(
        io.BytesIO(data), header=None, names=names, usecols=range(n_fields), dtype={names[1]: str, names[2]: str}
    )
    if table.isna().any().any():
        raise ValueError(f"{what}: malformed lines (missing fields)")
    return table


def _file_bytes(path: Path) -> tuple[bytes, int]:
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        data += b"\n"
    return data, sum(1 for line in data.splitlines() if line.strip())


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


def load_pabr_fingerprints(set_name: str = "set_1", data_dir=None) -> pd.DataFrame:
    """Packets recorded at the stationary reference points of ``hst/<set_name>/``.

    Parameters
    ----------
    set_name : {"set_1", "set_2"}
    data_dir : path, optional
        The PABR folder (default ``$WSNLIB_PABR_DIR``, else ``<ROOT>/data/raw/pabr``).

    Returns
    -------
    DataFrame
        Columns ``point`` (int, numbered in order of (x, y, z)), ``x``, ``y``, ``z`` (m),
        ``receiver`` (categorical, receiver order), ``timestamp`` (s), ``rssi`` (dBm); sorted
        by point, receiver, timestamp.  ``attrs``: ``set_name``, ``n_packets_read``,
        ``n_dropped_invalid_rssi``, ``source``.
    """
    if set_name not in FINGERPRINT_SETS:
        raise ValueError(f"set_name must be one of {FINGERPRINT_SETS}, got {set_name!r}")
    receivers = load_pabr_receivers(data_dir)
    folder = _require(_root(data_dir) / "hst" / set_name, f"fingerprint folder hst/{set_name}", kind="folder")
    mac_of = dict(zip(receivers["receiver"], receivers["mac"], strict=True))
    files = sorted(folder.glob("*.mbd"))
    if not files:
        raise FileNotFoundError(f"PABR fingerprint folder {folder} holds no .mbd files (set {PABR_DIR_ENV_VAR})")
    chunks, meta = [], []
    for path in files:
        match = _FINGERPRINT_NAME.match(path.name)
        if match is None:
            raise ValueError(f"{path}: file name does not follow <sensor>_<x>_<y>_<z>.mbd")
        sensor = match["sensor"]
        if sensor not in mac_of:
            raise ValueError(f"{path}: unknown receiver {sensor!r}; known: {list(mac_of)}")
        data, n_lines = _file_bytes(path)
        chunks.append(data)
        meta.append((sensor, float(match["x"]), float(match["y"]), float(match["z"]), n_lines))
    raw = _read_mbd(chunks, ["timestamp", "mac", "beacon", "rssi"], 4, f"hst/{set_name}")
    n_lines = np.array([m[4] for m in meta])
    if n_lines.sum() != len(raw):
        raise ValueError(f"hst/{set_name}: blank or malformed lines (read {len(raw)} rows, expected {n_lines.sum()})")
    sensor = np.repeat([m[0] for m in meta], n_lines)
    xyz = np.repeat(np.array([m[1:4] for m in meta]), n_lines, axis=0)
    expected_mac = np.array([mac_of[s] for s in sensor], dtype=object)
    mismatch = raw["mac"].to_numpy(dtype=object) != expected_mac
    if np.any(mismatch):
        row = int(np.argmax(mismatch))
        raise ValueError(f"hst/{set_name}: file of {sensor[row]} holds a packet of receiver MAC {raw['mac'][row]}")
    points, point_id = np.unique(xyz, axis=0, return_inverse=True)
    table = pd.DataFrame(
        {
            "point": np.asarray(point_id).reshape(-1),
            "x": xyz[:, 0],
            "y": xyz[:, 1],
            "z": xyz[:, 2],
            "receiver": pd.Categorical(sensor, categories=list(receivers["receiver"])),
            "timestamp": raw["timestamp"].to_numpy(dtype=float),
            "rssi": raw["rssi"].to_numpy(dtype=float),
        }
    )
    table = table.sort_values(["point", "receiver", "timestamp"], kind="stable").reset_index(drop=True)
    table = _drop_invalid(table, f"fingerprints {set_name}")
    table.attrs.update({"set_name": set_name, "n_points": len(points), "source": str(folder)})
    return table


def pabr_track_names(data_dir=None) -> list[str]:
    """Names of the tracks in ``trk/`` (file names less ``_all_sensors.mbd``), sorted."""
    folder = _require(_root(data_dir) / "trk", "track folder trk", kind="folder")
    return sorted(p.name[: -len(_TRACK_SUFFIX)] for p in folder.glob(f"*{_TRACK_SUFFIX}"))


def load_pabr_tracks(tracks=None, data_dir=None) -> pd.DataFrame:
    """Packets of the walked trajectories ``trk/<track>_all_sensors.mbd`` with ground truth.

    Parameters
    ----------
    tracks : str or list of str, optional
        Track names (see :func:`pabr_track_names`); default all.
    data_dir : path, optional
        The PABR folder.

    Returns
    -------
    DataFrame
        Columns ``track`` (categorical), ``timestamp`` (s), ``receiver`` (categorical),
        ``rssi`` (dBm), ``x``, ``y``, ``z`` (m, ground truth); in file (time) order within each
        track.  ``attrs``: ``n_packets_read``, ``n_dropped_invalid_rssi``, ``source``.
    """
    receivers = load_pabr_receivers(data_dir)
    known = pabr_track_names(data_dir)
    if tracks is None:
        names = known
    else:
        names = [tracks] if isinstance(tracks, str) else list(tracks)
        unknown = [n for n in names if n not in known]
        if unknown:
            raise ValueError(f"unknown PABR track(s) {unknown}; known tracks: {known}")
    if not names:
        raise FileNotFoundError(f"no *{_TRACK_SUFFIX} files in {pabr_dir(data_dir) / 'trk'} (set {PABR_DIR_ENV_VAR})")
    alias_of = dict(zip(receivers["mac"], receivers["receiver"], strict=True))
    folder = pabr_dir(data_dir) / "trk"
    chunks, counts = [], []
    for name in names:
        data, n_lines = _file_bytes(
            _require(folder / f"{name}{_TRACK_SUFFIX}", f"track file trk/{name}{_TRACK_SUFFIX}")
        )
        chunks.append(data)
        counts.append(n_lines)
    fields = ["timestamp", "mac", "beacon", "rssi", "x", "y", "z"] + [f"r{i}" for i in range(9)]
    raw = _read_mbd(chunks, fields, _TRACK_FIELDS, "trk")
    if sum(counts) != len(raw):
        raise ValueError(f"trk: blank or malformed lines (read {len(raw)} rows, expected {sum(counts)})")
    unknown_macs = sorted(set(raw["mac"]) - set(alias_of))
    if unknown_macs:
        raise ValueError(f"trk: packets from unknown receiver MAC(s) {unknown_macs}")
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
    table.attrs["source"] = str(folder)
    return table


@dataclasses.dataclass(frozen=True)
class PabrVectors:
    """RSS vectors built by :func:`pabr_vectors` (``n`` vectors, ``R`` receivers).

    Attributes
    ----------
    rss : ndarray (n, R)
        Mean RSS (dBm) per receiver in the window; NaN where none was heard (unless filled).
    positions : ndarray (n, 3)
        Mean position (m) of the window's packets.
    groups : ndarray (n,)
        The point id (fingerprints) or track name (tracks) of each vector.
    windows : ndarray of int (n,)
        Window / block index ``j`` within the group.
    times : ndarray (n,)
        Mean timestamp (s) of the window's packets.
    counts : ndarray of int (n, R)
        Packets averaged per receiver (0 = not heard).
    receivers : tuple of str
        Column order of ``rss`` and ``counts``.
    """

    rss: np.ndarray
    positions: np.ndarray
    groups: np.ndarray
    windows: np.ndarray
    times: np.ndarray
    counts: np.ndarray
    receivers: tuple

    def __len__(self) -> int:
        return self.rss.shape[0]


def pabr_vectors(
    table: pd.DataFrame,
    *,
    window_s: float | None = None,
    window_packets: int | None = None,
    fill: float | None = None,
    min_receivers: int = 1,
    group: str | None = None,
) -> PabrVectors:
    """RSS vectors (one value per receiver) from a long table of packets; see the module docstring.

    Parameters
    ----------
    table : DataFrame
        From :func:`load_pabr_fingerprints` or :func:`load_pabr_tracks` (columns ``timestamp``,
        ``receiver``, ``rssi``, ``x``, ``y``, ``z`` and the group column).
    window_s : float, optional
        Length (s) of the time windows.  Exactly one of ``window_s`` and ``window_packets``.
    window_packets : int, optional
        Packets per receiver averaged into each value (blocks of consecutive packets).
    fill : float, optional
        Value (dBm) replacing NaN (a receiver that heard nothing in the window); default keep NaN.
    min_receivers : int
        Drop vectors heard by fewer receivers than this (default 1: keep all).
    group : str, optional
        Column whose values are never mixed in a window; default ``"point"`` if present, else
        ``"track"``.

    Returns
    -------
    PabrVectors
        Ordered by group, then window.
    """
    if (window_s is None) == (window_packets is None):
        raise ValueError("give exactly one of window_s (seconds) and window_packets (packets per receiver)")
    if group is None:
        group = "point" if "point" in table.columns else "track"
    needed = [group, "timestamp", "receiver", "rssi", "x", "y", "z"]
    missing = [c for c in needed if c not in table.columns]
    if missing:
        raise ValueError(f"table lacks the column(s) {missing} (expected a load_pabr_* table)")
    if isinstance(min_receivers, bool) or not isinstance(min_receivers, int | np.integer) or min_receivers < 1:
        raise ValueError(f"min_receivers must be a positive integer, got {min_receivers!r}")
    if fill is not None and not np.isfinite(float(fill)):
        raise ValueError(f"fill must be a finite number (dBm) or None, got {fill!r}")
    receiver = table["receiver"]
    names = (
        list(receiver.cat.categories) if isinstance(receiver.dtype, pd.CategoricalDtype) else sorted(receiver.unique())
    )
    df = table[needed].copy()
    df["receiver"] = pd.Categorical(df["receiver"], categories=names)
    df = df.sort_values([group, "receiver", "timestamp"], kind="stable")
    if window_s is not None:
        window_s = float(window_s)
        if not np.isfinite(window_s) or window_s <= 0:
            raise ValueError(f"window_s must be a positive number of seconds, got {window_s!r}")
        t0 = df.groupby(group, observed=True)["timestamp"].transform("min")
        df["window"] = np.floor((df["timestamp"] - t0) / window_s).astype(np.int64)
    else:
        if isinstance(window_packets, bool) or not isinstance(window_packets, int | np.integer) or window_packets < 1:
            raise ValueError(f"window_packets must be a positive integer, got {window_packets!r}")
        by_receiver = df.groupby([group, "receiver"], observed=True)
        rank = by_receiver.cumcount().to_numpy()
        size = by_receiver["timestamp"].transform("size").to_numpy()
        keep = rank < (size // window_packets) * window_packets
        df = df.loc[keep].copy()
        df["window"] = rank[keep] // window_packets
    n_receivers = len(names)
    if df.empty:
        empty2 = np.empty((0, n_receivers))
        return PabrVectors(
            empty2, np.empty((0, 3)), np.empty(0), np.empty(0, int), np.empty(0), empty2.astype(int), tuple(names)
        )
    cells = df.groupby([group, "window", "receiver"], observed=True)["rssi"].agg(["mean", "size"])
    mean = cells["mean"].unstack("receiver").reindex(columns=names)
    count = cells["size"].unstack("receiver").reindex(columns=names).fillna(0)
    where = df.groupby([group, "window"], observed=True)[["x", "y", "z", "timestamp"]].mean().loc[mean.index]
    rss = mean.to_numpy(dtype=float)
    counts = count.to_numpy(dtype=np.int64)
    keep = (counts > 0).sum(axis=1) >= min_receivers
    if fill is not None:
        rss = np.where(np.isnan(rss), float(fill), rss)
    index = mean.index[keep]
    return PabrVectors(
        rss=rss[keep],
        positions=where[["x", "y", "z"]].to_numpy(dtype=float)[keep],
        groups=index.get_level_values(0).to_numpy(),
        windows=index.get_level_values(1).to_numpy(dtype=np.int64),
        times=where["timestamp"].to_numpy(dtype=float)[keep],
        counts=counts[keep],
        receivers=tuple(names),
    )
