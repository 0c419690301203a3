"""Raw IMU recordings: the in-memory :class:`Recording` and its CSV + JSON file format, and
the loader of the BROAD benchmark trials (:func:`load_broad`, see the section at the end).

The CSV + JSON format is what the notebooks read, and the one a user converts real
recordings into.

File format (format version 1)
------------------------------
A recording is two files side by side: ``<name>.csv`` (the samples) and ``<name>.json`` (the
sidecar).  :func:`write_recording` writes both; :func:`read_recording` reads them back.

**CSV** — comma separated, UTF-8, ``\\n`` line ends, one header line, then one row per
(sample, node), rows ordered by sample and, within a sample, by node in the sidecar's
``nodes`` order.  Columns, exactly these names in this order:

============  ======  ===============================================================
column        unit    meaning
============  ======  ===============================================================
time_s        s       sample time; identical for every node of a sample
node          —       node name (text, no commas or quotes), one of the sidecar's nodes
gyr_x_rad_s   rad/s   angular rate, body (sensor) frame, x / y / z
gyr_y_rad_s
gyr_z_rad_s
acc_x_m_s2    m/s²    specific force, body frame (reads +g upward at rest), x / y / z
acc_y_m_s2
acc_z_m_s2
mag_x_uT      µT      magnetic field, body frame, x / y / z
mag_y_uT
mag_z_uT
quat_w        —       optional ground truth: unit quaternion [w, x, y, z] rotating body
quat_x                vectors into the earth frame ENU (x east, y north, z up).  Either
quat_y                all four columns or none (a real recording without ground truth
quat_z                leaves them out).
============  ======  ===============================================================

Numbers are written with ``%.9g`` (9 significant digits), so writing the same recording
twice gives byte-identical files; reading back agrees within that precision (relative
≈ 5e-10).  Every value must be finite; the time stamps must be strictly increasing and the
same for every node; missing samples are not allowed (packet loss is applied later, as a
mask, never by deleting rows).

**JSON sidecar** — an object with the keys

* ``format``: ``"wsnlib-recording"``; ``format_version``: ``1``;
* ``fs_hz``: nominal sampling rate (Hz);
* ``nodes``: list of node names, in row order;
* ``units``: ``{"time": "s", "gyr": "rad/s", "acc": "m/s^2", "mag": "uT"}``;
* ``frame_convention``: text describing the body and earth frames (informative);
* ``has_quaternions``: whether the CSV has the ``quat_*`` columns;
* ``metadata``: free JSON object (generator, parameters, seed, subject, …);
* ``csv_rows``, ``csv_sha256``: the CSV's number of data rows and the SHA-256 of its bytes
  (written by every writer; a reader refuses a CSV that disagrees with them — a truncated or
  edited copy — and skips the check when a hand-made sidecar leaves both out).

Written with sorted keys and two-space indent; both files are written atomically (temporary
file, then rename).  If the sidecar is missing,
:func:`read_recording` infers ``fs`` from the median time step and the node order from the
first sample, and uses empty metadata.

The signal conventions are those of :mod:`wsnlib` (see ``wsnlib/__init__.py``).

BROAD (real recordings with optical ground truth)
-------------------------------------------------
:func:`load_broad` reads trials of the Berlin Robust Orientation Estimation Assessment
Dataset:

    D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD—A Benchmark for Robust Inertial
    Orientation Estimation", *Data* 6(7):72, 2021, doi:10.3390/data6070072.
    Data licensed CC BY 4.0 — credit the authors wherever results from it are shown.

The files are the MATLAB versions (``data_mat/<trial>.mat``) of the public repository
github.com/dlaidig/broad, pinned to commit :data:`BROAD_COMMIT`.  :data:`BROAD_REGISTRY` (shipped
as ``wsnlib/registry/broad.tsv``) lists all 39 trials of the dataset and its ``trials.json``,
with the SHA-256 where known (30 trials) and the git blob id of every file (SHA-1 of
``b"blob <size>\\0"`` + content), which verifies the other nine.  :func:`broad_trials` lists the
trials, or with ``present_only=True`` those whose file is in the folder.

Folder, first match wins: the ``data_dir`` argument; else the environment variable
``WSNLIB_BROAD_DIR``; else ``<ROOT>/data/raw/broad/`` (gitignored; ROOT is the checkout,
:data:`wsnlib.paths.ROOT`).  A missing file is downloaded with pooch from
``https://raw.githubusercontent.com/dlaidig/broad/<BROAD_COMMIT>/data_mat/<file>`` into that
folder (unless ``download=False``) and kept only if its SHA-256 (else its git blob id) matches.
Every file, whether downloaded or already there, is hash-checked before it is read; a mismatch
raises ``ValueError`` naming the file and both hashes (a corrupt file is never half-read, and never
silently replaced: delete it to download it again).  The verified hash is remembered per
(path, size, modification time) within the process, so reloading does not rehash.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from wsnlib import paths
from wsnlib._files import atomic_write_bytes, atomic_write_text, sha256_of
from wsnlib._validation import as_float_array, check_positive

FORMAT_NAME = "wsnlib-recording"
FORMAT_VERSION = 1

#: Column names of the CSV, in order; the last four are optional.
SIGNAL_COLUMNS: dict[str, tuple[str, str, str]] = {
    "gyr": ("gyr_x_rad_s", "gyr_y_rad_s", "gyr_z_rad_s"),
    "acc": ("acc_x_m_s2", "acc_y_m_s2", "acc_z_m_s2"),
    "mag": ("mag_x_uT", "mag_y_uT", "mag_z_uT"),
}
QUAT_COLUMNS: tuple[str, str, str, str] = ("quat_w", "quat_x", "quat_y", "quat_z")
BASE_COLUMNS: tuple[str, ...] = (
    "time_s",
    "node",
    *SIGNAL_COLUMNS["gyr"],
    *SIGNAL_COLUMNS["acc"],
    *SIGNAL_COLUMNS["mag"],
)
ALL_COLUMNS: tuple[str, ...] = BASE_COLUMNS + QUAT_COLUMNS

#: Units written to (and required in) the sidecar.
UNITS = {"time": "s", "gyr": "rad/s", "acc": "m/s^2", "mag": "uT"}

FRAME_CONVENTION = (
    "Signals in the sensor body frame. quat_[wxyz] is a unit quaternion [w, x, y, z] rotating "
    "body-frame vectors into the earth frame ENU (x east, y north, z up): v_E = q v_B q*. "
    "acc is specific force (+g along earth z at rest)."
)

FLOAT_FORMAT = "%.9g"

#: Sidecar keys written by every recording format (:func:`write_table_with_sidecar`): the
#: number of data rows of the CSV and the SHA-256 of its bytes, checked by the readers.
CSV_ROWS_KEY = "csv_rows"
CSV_SHA256_KEY = "csv_sha256"

#: Largest tolerated deviation of a ground-truth quaternion's norm from 1 when reading.
_QUAT_NORM_TOL = 1e-6


@dataclass
class Recording:
    """One recording of several IMU nodes sampled together.

    Attributes
    ----------
    fs : float
        Nominal sampling rate (Hz).
    time_s : numpy.ndarray, shape (T,)
        Sample times (s), strictly increasing.
    nodes : tuple of str
        Node names, in the order of the node axis.
    gyr : numpy.ndarray, shape (N_nodes, T, 3)
        Angular rate, body frame (rad/s).
    acc : numpy.ndarray, shape (N_nodes, T, 3)
        Specific force, body frame (m/s²).
    mag : numpy.ndarray, shape (N_nodes, T, 3)
        Magnetic field, body frame (µT).
    quat_true : numpy.ndarray, shape (N_nodes, T, 4), or None
        Ground-truth orientation (body → ENU), unit norm; None when unknown.
    metadata : dict
        Free, JSON-serialisable provenance (generator, parameters, seed, …).
    """

    fs: float
    time_s: np.ndarray
    nodes: tuple[str, ...]
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray
    quat_true: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        self.fs = check_positive(self.fs, "fs")
        self.time_s = as_float_array(self.time_s, "time_s")
        if self.time_s.ndim != 1:
            raise ValueError(f"time_s must be 1-D, got shape {self.time_s.shape}")
        if self.time_s.size > 1 and np.any(np.diff(self.time_s) <= 0.0):
            raise ValueError("time_s must be strictly increasing")
        if isinstance(self.nodes, str):
            raise ValueError("nodes must be a sequence of node names, not a single string")
        self.nodes = tuple(self.nodes)
        if not self.nodes:
            raise ValueError("nodes must name at least one node")
        for name in self.nodes:
            _check_node_name(name)
        if len(set(self.nodes)) != len(self.nodes):
            raise ValueError(f"nodes must be unique, got {self.nodes}")
        shape = (len(self.nodes), self.time_s.size)
        for name in ("gyr", "acc", "mag"):
            arr = as_float_array(getattr(self, name), name, last_dim=3)
            if arr.shape != shape + (3,):
                raise ValueError(f"{name} must have shape {shape + (3,)}, got {arr.shape}")
            setattr(self, name, arr)
        if self.quat_true is not None:
            quat = as_float_array(self.quat_true, "quat_true", last_dim=4)
            if quat.shape != shape + (4,):
                raise ValueError(f"quat_true must have shape {shape + (4,)}, got {quat.shape}")
            self.quat_true = quat
        if not isinstance(self.metadata, dict):
            raise ValueError(f"metadata must be a dict, got {type(self.metadata).__name__}")

    @property
    def n_samples(self) -> int:
        """Number of samples T."""
        return self.time_s.size

    def node_index(self, node: str) -> int:
        """Position of ``node`` on the node axis; ``ValueError`` if absent."""
        try:
            return self.nodes.index(node)
        except ValueError:
            raise ValueError(f"node {node!r} is not in this recording {self.nodes}") from None


def _check_node_name(name) -> None:
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"node names must be non-empty strings, got {name!r}")
    if name != name.strip() or any(c in name for c in ',"\n\r'):
        raise ValueError(
            f"node name {name!r} must not contain commas, quotes, line breaks or surrounding spaces"
        )


def sidecar_path(path) -> Path:
    """The JSON sidecar that belongs to CSV ``path``: same name, suffix ``.json``."""
    return Path(path).with_suffix(".json")


def _json_default(value):
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (tuple, set, frozenset)):
        return list(value)
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def write_table_with_sidecar(frame, path: Path, sidecar: dict, float_format: str, what: str = "metadata") -> Path:
    """Write ``frame`` as CSV and ``sidecar`` as ``<name>.json`` (sorted keys), byte-reproducibly.

    Shared by the recording formats of :mod:`wsnlib.datasets`, :mod:`wsnlib.rss` and
    :mod:`wsnlib.accel_format`.  ``what`` names the user-supplied part in the error raised
    when the sidecar is not JSON-serialisable.  The sidecar gains :data:`CSV_ROWS_KEY` (the
    number of data rows) and :data:`CSV_SHA256_KEY` (the SHA-256 of the CSV's bytes), which
    :func:`load_sidecar` checks, so a truncated or altered copy is refused.  Both files are
    written atomically (temporary file + rename), the CSV first.
    """
    csv_bytes = frame.to_csv(None, index=False, float_format=float_format, lineterminator="\n").encode("utf-8")
    sidecar = {**sidecar, CSV_ROWS_KEY: len(frame), CSV_SHA256_KEY: hashlib.sha256(csv_bytes).hexdigest()}
    try:
        text = json.dumps(sidecar, indent=2, sort_keys=True, default=_json_default, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} cannot be written as JSON: {exc}") from exc
    atomic_write_bytes(path, csv_bytes)
    atomic_write_text(sidecar_path(path), text + "\n")
    return path


def _check_csv_integrity(path: Path, meta: dict, side: Path) -> None:
    """Compare the CSV with the row count and SHA-256 its sidecar recorded (when it has them)."""
    if CSV_ROWS_KEY not in meta and CSV_SHA256_KEY not in meta:
        return  # a hand-converted file: nothing to check against
    rows, digest = meta.get(CSV_ROWS_KEY), meta.get(CSV_SHA256_KEY)
    if isinstance(rows, bool) or not isinstance(rows, int) or rows < 0:
        raise ValueError(f"{side}: {CSV_ROWS_KEY!r} must be a non-negative integer, got {rows!r}")
    if not isinstance(digest, str) or len(digest) != 64 or any(c not in "0123456789abcdef" for c in digest):
        raise ValueError(f"{side}: {CSV_SHA256_KEY!r} must be 64 lower-case hex digits, got {digest!r}")
    data = path.read_bytes()
    lines = data.count(b"\n") + (1 if data and not data.endswith(b"\n") else 0)
    found = max(lines - 1, 0)  # minus the header line
    if found != rows:
        raise ValueError(
            f"{path}: has {found} data rows but its sidecar {side.name} says {rows}: the file is "
            f"truncated or was changed after it was written (write it again with the writer)"
        )
    actual = hashlib.sha256(data).hexdigest()
    if actual != digest:
        raise ValueError(
            f"{path}: SHA-256 {actual[:12]}… differs from {CSV_SHA256_KEY!r} {digest[:12]}… in its sidecar "
            f"{side.name}: the file was damaged or changed after it was written (write it again with the writer)"
        )


def finite_column(frame, column: str, where) -> np.ndarray:
    """Column ``column`` of a read CSV table as finite floats, or ``ValueError`` naming file, column and row."""
    values = pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=float)
    bad = ~np.isfinite(values)
    if np.any(bad):
        row = int(np.argmax(bad))
        raise ValueError(
            f"{where}: column {column!r} has a non-numeric or non-finite value "
            f"{frame[column].iloc[row]!r} at data row {row + 1}"
        )
    return values


def load_sidecar(path: Path, format_name: str, format_version: int, *, required: bool, what: str) -> dict | None:
    """Read and check the ``<name>.json`` sidecar of a recording file (format name and version).

    Returns None when it is missing and not ``required``; raises ``ValueError`` naming the
    sidecar otherwise (``what`` says which kind of file needs it).  When the sidecar records
    :data:`CSV_ROWS_KEY` and :data:`CSV_SHA256_KEY` (every file the writers produce), the CSV
    ``path`` must have that many data rows and that SHA-256, else ``ValueError`` naming the
    file (truncated or changed after writing).  A hand-made sidecar may leave both out.
    """
    side = sidecar_path(path)
    if not side.exists():
        if required:
            raise ValueError(f"{side}: missing sidecar ({what} needs its .json file)")
        return None
    try:
        meta = json.loads(side.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{side}: not valid JSON ({exc})") from exc
    if not isinstance(meta, dict):
        raise ValueError(f"{side}: must hold a JSON object")
    if meta.get("format") != format_name:
        raise ValueError(f"{side}: 'format' must be {format_name!r}, got {meta.get('format')!r}")
    if meta.get("format_version") != format_version:
        raise ValueError(
            f"{side}: unsupported 'format_version' {meta.get('format_version')!r} (this reader knows {format_version})"
        )
    _check_csv_integrity(Path(path), meta, side)
    return meta


def check_sidecar_units(meta: dict, units: dict, side: Path) -> None:
    """``ValueError`` naming the sidecar unless ``meta["units"]`` gives every unit of ``units`` as documented."""
    found = meta.get("units")
    if not isinstance(found, dict):
        raise ValueError(f"{side}: 'units' must be an object {units}, got {found!r}")
    for key, unit in units.items():
        if found.get(key) != unit:
            raise ValueError(
                f"{side}: units[{key!r}] must be {unit!r} (convert the data first), got {found.get(key)!r}"
            )


def write_recording(recording: Recording, path) -> Path:
    """Write ``recording`` as ``path`` (CSV) plus the sidecar ``path.with_suffix('.json')``.

    Parameters
    ----------
    recording : Recording
    path : str or pathlib.Path
        CSV file to write (parent folders are created); conventionally ends in ``.csv``.

    Returns
    -------
    pathlib.Path
        The CSV path.  Writing the same recording again gives byte-identical files.

    Raises
    ------
    ValueError
        If ``path`` ends in ``.json`` or the metadata is not JSON serialisable.
    """
    if not isinstance(recording, Recording):
        raise ValueError(f"recording must be a Recording, got {type(recording).__name__}")
    path = Path(path)
    if path.suffix.lower() == ".json":
        raise ValueError(f"path must name the CSV file, not the sidecar: {path}")
    n_nodes, n_samples = len(recording.nodes), recording.n_samples
    data: dict[str, object] = {
        "time_s": np.repeat(recording.time_s, n_nodes),
        "node": np.tile(np.array(recording.nodes, dtype=object), n_samples),
    }
    for key, columns in SIGNAL_COLUMNS.items():
        values = np.swapaxes(getattr(recording, key), 0, 1).reshape(-1, 3)
        for i, column in enumerate(columns):
            data[column] = values[:, i]
    if recording.quat_true is not None:
        values = np.swapaxes(recording.quat_true, 0, 1).reshape(-1, 4)
        for i, column in enumerate(QUAT_COLUMNS):
            data[column] = values[:, i]
    frame = pd.DataFrame(data)
    # Adding 0.0 turns -0.0 into 0.0, so that equal values always print the same way.
    numeric = [c for c in frame.columns if c != "node"]
    frame[numeric] = frame[numeric] + 0.0
    sidecar = {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "fs_hz": recording.fs,
        "nodes": list(recording.nodes),
        "units": UNITS,
        "frame_convention": FRAME_CONVENTION,
        "has_quaternions": recording.quat_true is not None,
        "metadata": recording.metadata,
    }
    return write_table_with_sidecar(frame, path, sidecar, FLOAT_FORMAT, what="recording.metadata")


def _read_sidecar(path: Path) -> dict | None:
    side = sidecar_path(path)
    meta = load_sidecar(path, FORMAT_NAME, FORMAT_VERSION, required=False, what="a recording")
    if meta is None:
        return None
    for key in ("fs_hz", "nodes", "units"):
        if key not in meta:
            raise ValueError(f"{side}: missing key {key!r}")
    try:
        check_positive(meta["fs_hz"], "fs_hz")
    except ValueError as exc:
        raise ValueError(f"{side}: {exc}") from exc
    if not isinstance(meta["nodes"], list) or not meta["nodes"]:
        raise ValueError(f"{side}: 'nodes' must be a non-empty list of node names")
    units = meta["units"]
    if not isinstance(units, dict):
        raise ValueError(f"{side}: 'units' must be an object")
    for key, unit in UNITS.items():
        if units.get(key) != unit:
            raise ValueError(
                f"{side}: units[{key!r}] must be {unit!r} (convert the data first), "
                f"got {units.get(key)!r}"
            )
    if not isinstance(meta.get("metadata", {}), dict):
        raise ValueError(f"{side}: 'metadata' must be an object")
    return meta


def read_recording(path) -> Recording:
    """Read a recording written by :func:`write_recording` (or converted into its format).

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file; its sidecar ``path.with_suffix('.json')`` is read when present.

    Returns
    -------
    Recording
        ``quat_true`` is None when the CSV has no ``quat_*`` columns.  Quaternion norms must
        be within 1e-6 of 1; they are returned as read (not renormalised), so that reading
        and writing a file again reproduces it byte for byte.

    Raises
    ------
    ValueError
        Naming the file and the column: missing, unknown or misordered columns, only some
        ``quat_*`` columns, non-numeric or non-finite values, unknown nodes, nodes with
        different time stamps or sample counts, time not strictly increasing, a time step
        that disagrees with the sidecar's ``fs_hz`` by more than 1 %, or a bad sidecar.
    """
    path = Path(path)
    if not path.exists():
        raise ValueError(f"{path}: no such file")
    meta = _read_sidecar(path)
    try:
        frame = pd.read_csv(path, dtype={"node": str}, keep_default_na=False, na_values=[])
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot be parsed as CSV ({exc})") from exc

    columns = list(frame.columns)
    missing = [c for c in BASE_COLUMNS if c not in columns]
    if missing:
        raise ValueError(f"{path}: missing column(s) {missing}")
    unknown = [c for c in columns if c not in ALL_COLUMNS]
    if unknown:
        raise ValueError(f"{path}: unknown column(s) {unknown}; expected {list(ALL_COLUMNS)}")
    quat_present = [c for c in QUAT_COLUMNS if c in columns]
    if quat_present and len(quat_present) != 4:
        absent = [c for c in QUAT_COLUMNS if c not in columns]
        raise ValueError(f"{path}: quaternion columns must come all four or none; missing {absent}")
    expected = list(BASE_COLUMNS) + (list(QUAT_COLUMNS) if quat_present else [])
    if columns != expected:
        raise ValueError(f"{path}: columns must be in the order {expected}, got {columns}")
    if len(frame) == 0:
        raise ValueError(f"{path}: has no data rows")
    if meta is not None and bool(meta.get("has_quaternions", bool(quat_present))) != bool(
        quat_present
    ):
        raise ValueError(
            f"{sidecar_path(path)}: 'has_quaternions' is {meta.get('has_quaternions')!r} "
            f"but {path} {'has' if quat_present else 'lacks'} the quat_* columns"
        )

    numeric = {}
    for column in expected:
        if column == "node":
            continue
        numeric[column] = finite_column(frame, column, path)
    node_col = frame["node"].to_numpy(dtype=object)
    for row, name in enumerate(node_col):
        if not isinstance(name, str) or not name.strip():
            raise ValueError(f"{path}: column 'node' is empty at data row {row + 1}")

    if meta is not None:
        nodes = tuple(meta["nodes"])
        for name in nodes:
            try:
                _check_node_name(name)
            except ValueError as exc:
                raise ValueError(f"{sidecar_path(path)}: {exc}") from exc
        stray = sorted(set(node_col) - set(nodes))
        if stray:
            raise ValueError(f"{path}: column 'node' has node(s) {stray} not listed in the sidecar")
    else:
        nodes = tuple(dict.fromkeys(node_col))

    n_nodes = len(nodes)
    counts = {name: int(np.sum(node_col == name)) for name in nodes}
    if len(set(counts.values())) != 1:
        raise ValueError(f"{path}: column 'node': nodes have different sample counts {counts}")
    n_samples = counts[nodes[0]]
    if n_samples == 0:
        raise ValueError(f"{path}: column 'node': node {nodes[0]!r} has no rows")
    expected_nodes = np.tile(np.array(nodes, dtype=object), n_samples)
    if not np.array_equal(node_col, expected_nodes):
        row = int(np.argmax(node_col != expected_nodes))
        raise ValueError(
            f"{path}: column 'node': rows must cycle through {list(nodes)} for every sample; "
            f"data row {row + 1} has {node_col[row]!r}, expected {expected_nodes[row]!r}"
        )

    time = numeric["time_s"].reshape(n_samples, n_nodes)
    if not np.all(time == time[:, :1]):
        row = int(np.argmax(np.any(time != time[:, :1], axis=1)))
        raise ValueError(
            f"{path}: column 'time_s': nodes have different time stamps at sample {row} "
            f"({time[row].tolist()})"
        )
    time_s = time[:, 0]
    if n_samples > 1 and np.any(np.diff(time_s) <= 0.0):
        row = int(np.argmax(np.diff(time_s) <= 0.0))
        raise ValueError(f"{path}: column 'time_s' is not strictly increasing at sample {row + 1}")

    if meta is not None:
        fs = float(meta["fs_hz"])
        if n_samples > 1:
            median_step = float(np.median(np.diff(time_s)))
            if not math.isclose(median_step, 1.0 / fs, rel_tol=0.01):
                raise ValueError(
                    f"{path}: column 'time_s' has median step {median_step:.6g} s, which "
                    f"disagrees with fs_hz = {fs:g} in {sidecar_path(path)}"
                )
        metadata = dict(meta.get("metadata", {}))
    else:
        if n_samples < 2:
            raise ValueError(f"{path}: without a sidecar, fs needs at least two samples")
        fs = 1.0 / float(np.median(np.diff(time_s)))
        metadata = {}

    def block(cols):
        stacked = np.stack([numeric[c] for c in cols], axis=-1)
        return np.swapaxes(stacked.reshape(n_samples, n_nodes, len(cols)), 0, 1).copy()

    quat = None
    if quat_present:
        quat = block(QUAT_COLUMNS)
        norm = np.linalg.norm(quat, axis=-1)
        if np.any(np.abs(norm - 1.0) > _QUAT_NORM_TOL):
            node, sample = np.argwhere(np.abs(norm - 1.0) > _QUAT_NORM_TOL)[0]
            raise ValueError(
                f"{path}: columns quat_*: not a unit quaternion (norm {norm[node, sample]:.9g}) "
                f"for node {nodes[node]!r} at sample {sample}"
            )

    return Recording(
        fs=fs,
        time_s=time_s.copy(),
        nodes=nodes,
        gyr=block(SIGNAL_COLUMNS["gyr"]),
        acc=block(SIGNAL_COLUMNS["acc"]),
        mag=block(SIGNAL_COLUMNS["mag"]),
        quat_true=quat,
        metadata=metadata,
    )


# --------------------------------------------------------------------------------------------
# BROAD benchmark trials (Laidig et al. 2021, CC BY 4.0); see the module docstring.
# --------------------------------------------------------------------------------------------

#: Commit of github.com/dlaidig/broad the files are pinned to.
BROAD_COMMIT = "7e2f8189bb4a3ac91eae32c69b6bc87f08a6e2ad"

#: Download address of a file of the dataset's ``data_mat/`` folder.
BROAD_URL = "https://raw.githubusercontent.com/dlaidig/broad/{commit}/data_mat/{filename}"

#: Environment variable naming the folder that holds the BROAD files.
BROAD_DIR_ENV_VAR = "WSNLIB_BROAD_DIR"


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


def _read_broad_registry() -> dict[str, RegistryEntry]:
    from importlib import resources

    text = resources.files("wsnlib").joinpath("registry", "broad.tsv").read_text(encoding="utf-8")
    rows = [line.split("\t") for line in text.splitlines() if line and not line.startswith("#")]
    if rows[0] != ["file", "sha256", "git_blob_sha1"]:
        raise ValueError(f"wsnlib/registry/broad.tsv: unexpected header {rows[0]}")
    return {name: RegistryEntry(None if sha == "-" else sha, blob) for name, sha, blob in rows[1:]}


#: File name → expected content (:class:`RegistryEntry`) of every file of the dataset's
#: ``data_mat/`` folder at :data:`BROAD_COMMIT`: the 39 trials and ``trials.json``.  The SHA-256
#: is known for 30 trials; the other 9 (13, 17, 19, 20, 22, 23, 37, 38, 39) are verified by
#: their git blob id.  Shipped as ``wsnlib/registry/broad.tsv``.
BROAD_REGISTRY: dict[str, RegistryEntry] = _read_broad_registry()

#: Largest tolerated deviation of a reference quaternion's norm from 1.
_BROAD_QUAT_NORM_TOL = 1e-6

#: Verified files: (resolved path, size, mtime_ns) → the expected hash it matched, so
#: reloading does not rehash.
_VERIFIED_HASHES: dict[tuple[str, int, int], str] = {}


def git_blob_sha1_of(path: Path) -> str:
    """Git's blob id of a file: hex SHA-1 of ``b"blob <size in bytes>\\0"`` followed by its bytes."""
    import hashlib

    path = Path(path)
    digest = hashlib.sha1(f"blob {path.stat().st_size}\0".encode("ascii"))
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def broad_trials(present_only: bool = False, data_dir=None) -> list[str]:
    """Names of the BROAD trials (without ``.mat``), in trial-number order.

    Parameters
    ----------
    present_only : bool
        False (default): all 39 trials of the dataset (each loads if its file is present or can
        be downloaded).  True: only those whose ``.mat`` file is in the folder now (not yet
        hash-checked: :func:`load_broad` does that).
    data_dir : str or pathlib.Path, optional
        Folder looked into when ``present_only``; default see :func:`broad_dir`.
    """
    if not isinstance(present_only, bool):
        raise ValueError(f"present_only must be True or False, got {present_only!r}")
    names = sorted(name[: -len(".mat")] for name in BROAD_REGISTRY if name.endswith(".mat"))
    if present_only:
        folder = broad_dir(data_dir)
        names = [name for name in names if (folder / f"{name}.mat").is_file()]
    return names


def broad_trial_numbers(trials) -> str:
    """``"02, 07, 16"``: the leading numbers of BROAD trial names, for sentences; ``"none"`` if empty."""
    numbers = [str(trial).split("_", 1)[0] for trial in trials]
    return ", ".join(numbers) or "none"


def broad_dir(data_dir=None) -> Path:
    """Folder of the BROAD files: ``data_dir``, else ``$WSNLIB_BROAD_DIR``, else ``<ROOT>/data/raw/broad``.

    The folder is not created here (only a download creates it).
    """
    if data_dir is not None:
        return Path(data_dir).expanduser().resolve()
    override = os.environ.get(BROAD_DIR_ENV_VAR)
    if override:
        return Path(override).expanduser().resolve()
    return paths.ROOT / "data" / "raw" / "broad"


def _broad_trial_name(trial) -> str:
    known = broad_trials()
    if isinstance(trial, bool):
        raise ValueError(f"trial must be a trial name or number, got {trial!r}; known trials: {known}")
    if isinstance(trial, int | np.integer):
        matches = [name for name in known if int(name.split("_", 1)[0]) == int(trial)]
    elif isinstance(trial, str):
        name = trial[: -len(".mat")] if trial.endswith(".mat") else trial
        matches = [name] if name in known else []
    else:
        raise ValueError(f"trial must be a trial name or number, got {type(trial).__name__}; known trials: {known}")
    if not matches:
        raise ValueError(f"unknown BROAD trial {trial!r}; known trials: {known}")
    return matches[0]


def _verify_file(path: Path, expected: RegistryEntry) -> None:
    """Raise ``ValueError`` naming ``path`` and both hashes unless its content is ``expected``.

    Checks the SHA-256 where the registry knows it, else the git blob id.
    """
    if expected.sha256 is not None:
        kind, wanted, compute = "SHA-256", expected.sha256, sha256_of
    elif expected.git_blob_sha1 is not None:
        kind, wanted, compute = "git blob id", expected.git_blob_sha1, git_blob_sha1_of
    else:
        raise ValueError(f"{path}: the registry holds no hash to verify it with")
    stat = path.stat()
    key = (str(path.resolve()), stat.st_size, stat.st_mtime_ns)
    if _VERIFIED_HASHES.get(key) == wanted:
        return
    actual = compute(path)
    if actual != wanted:
        raise ValueError(
            f"{path}: {kind} is {actual}, expected {wanted} (the file is corrupt, truncated or "
            f"another version); delete it to download it again"
        )
    _VERIFIED_HASHES[key] = actual


def broad_file(filename: str, data_dir=None, *, download: bool = True, downloader=None) -> Path:
    """Path of a verified BROAD file, downloading it first if it is missing.

    Parameters
    ----------
    filename : str
        A key of :data:`BROAD_REGISTRY`, e.g. ``"02_undisturbed_slow_rotation_B.mat"``.
    data_dir : str or pathlib.Path, optional
        Folder; default see :func:`broad_dir`.
    download : bool
        If False, a missing file raises ``FileNotFoundError`` instead of being downloaded.
    downloader : callable, optional
        Passed on to :func:`pooch.retrieve`: called as ``downloader(url, output_file, pooch)``
        and must write the file at ``url`` to the path ``output_file`` (default: pooch's HTTP
        downloader).  The tests inject a local copier here.

    Returns
    -------
    pathlib.Path
        The file, whose SHA-256 (or, where the registry has none, git blob id) matches the
        registry.

    Raises
    ------
    ValueError
        Unknown ``filename``; or a hash mismatch, of a file already present or of a download
        (a failed download leaves no file behind).
    FileNotFoundError
        The file is missing and ``download`` is False.
    OSError
        The download itself failed (no network, HTTP error).
    """
    if filename not in BROAD_REGISTRY:
        raise ValueError(f"unknown BROAD file {filename!r}; known files: {sorted(BROAD_REGISTRY)}")
    expected = BROAD_REGISTRY[filename]
    folder = broad_dir(data_dir)
    path = folder / filename
    if not path.exists():
        url = BROAD_URL.format(commit=BROAD_COMMIT, filename=filename)
        if not download:
            raise FileNotFoundError(
                f"{path} does not exist; download it from {url}, point ${BROAD_DIR_ENV_VAR} or "
                f"data_dir at a folder holding it, or call with download=True"
            )
        _download(url, path, expected, downloader, env_var=BROAD_DIR_ENV_VAR)
    _verify_file(path, expected)
    return path


def _download(url: str, path: Path, expected: RegistryEntry, downloader, *, env_var: str) -> None:
    """Download ``url`` to ``path`` with pooch, keeping it only if it matches ``expected``.

    With a SHA-256, pooch checks it (writing to a temporary file in the same folder and moving
    it into place only on a match).  With only a git blob id, the file is downloaded under a
    temporary name, checked here, then renamed into place (``os.replace``) or deleted.
    """
    import pooch

    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f".{path.name}.download")
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
    except ValueError as exc:
        wanted = f"SHA-256 {expected.sha256}" if expected.sha256 else f"git blob id {expected.git_blob_sha1}"
        raise ValueError(
            f"download of {path.name} from {url} failed the hash check (expected {wanted}); "
            f"nothing was written to {path}. Details: {exc}"
        ) from exc
    except OSError as exc:
        raise OSError(
            f"could not download {url} to {path}: {exc}. Without network, copy the file there "
            f"by hand or set ${env_var} to a folder holding it"
        ) from exc
    finally:
        partial.unlink(missing_ok=True)


def broad_trial_info(data_dir=None, *, download: bool = True, downloader=None) -> dict:
    """The dataset's ``trials.json`` (groups, and per trial its description and groups), parsed."""
    path = broad_file("trials.json", data_dir, download=download, downloader=downloader)
    return json.loads(path.read_text(encoding="utf-8"))


@dataclass(frozen=True, eq=False)
class BroadTrial:
    """One BROAD trial: IMU signals and the optical reference orientation, sampled together.

    The arrays are read-only copies.  Credit: Laidig et al., BROAD, Data 6(7):72, 2021
    (CC BY 4.0).

    Attributes
    ----------
    name : str
        Trial name, e.g. ``"02_undisturbed_slow_rotation_B"``.
    fs : float
        Sampling rate (Hz); 2000/7 ≈ 285.714 Hz in the files (stored to full double precision).
    time_s : numpy.ndarray, shape (T,)
        Sample times (s), ``k / fs`` (the files carry no time stamps).
    gyr : numpy.ndarray, shape (T, 3)
        Angular rate, IMU body frame (rad/s), file key ``imu_gyr``.
    acc : numpy.ndarray, shape (T, 3)
        Specific force, IMU body frame (m/s², +g upward at rest), file key ``imu_acc``.
    mag : numpy.ndarray, shape (T, 3)
        Magnetic field, IMU body frame (µT), file key ``imu_mag``.
    quat_ref : numpy.ndarray, shape (T, 4)
        Optical reference orientation ``[w, x, y, z]``, body → ENU, unit norm (file key
        ``opt_quat``, already aligned to the IMU by the dataset's authors).  Rows are NaN
        where the markers were lost; they are kept NaN (never interpolated).
    movement : numpy.ndarray of bool, shape (T,)
        Samples of the movement phase, the ones BROAD's errors are computed on.
    info : str
        The file's description text.
    """

    name: str
    fs: float
    time_s: np.ndarray = field(repr=False)
    gyr: np.ndarray = field(repr=False)
    acc: np.ndarray = field(repr=False)
    mag: np.ndarray = field(repr=False)
    quat_ref: np.ndarray = field(repr=False)
    movement: np.ndarray = field(repr=False)
    info: str = field(default="", repr=False)

    #: Attribute → key in the .mat file, for error messages.
    _FILE_KEYS = {"gyr": "imu_gyr", "acc": "imu_acc", "mag": "imu_mag", "quat_ref": "opt_quat",
                  "movement": "movement"}

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"name must be a non-empty string, got {self.name!r}")
        where = f"BROAD trial {self.name!r}"
        object.__setattr__(self, "fs", check_positive(self.fs, f"{where}: fs"))
        time_s = self._frozen(as_float_array(self.time_s, f"{where}: time_s"))
        if time_s.ndim != 1 or time_s.size < 2:
            raise ValueError(f"{where}: time_s must be 1-D with at least 2 samples, got shape {time_s.shape}")
        if np.any(np.diff(time_s) <= 0.0):
            raise ValueError(f"{where}: time_s must be strictly increasing")
        object.__setattr__(self, "time_s", time_s)
        n = time_s.size
        for attr in ("gyr", "acc", "mag"):
            label = f"{where}: {attr} (file key {self._FILE_KEYS[attr]!r})"
            arr = np.asarray(getattr(self, attr))
            if arr.shape != (n, 3):
                raise ValueError(f"{label} must have shape {(n, 3)}, got {arr.shape}")
            object.__setattr__(self, attr, self._frozen(as_float_array(arr, label)))
        label = f"{where}: quat_ref (file key 'opt_quat')"
        quat = np.array(self.quat_ref, dtype=float)
        if quat.shape != (n, 4):
            raise ValueError(f"{label} must have shape {(n, 4)}, got {quat.shape}")
        nan_rows = np.isnan(quat).any(axis=-1)
        if np.any(np.isinf(quat)) or np.any(nan_rows & ~np.isnan(quat).all(axis=-1)):
            raise ValueError(f"{label}: rows must be finite or entirely NaN (lost markers)")
        norm_error = np.abs(np.linalg.norm(quat[~nan_rows], axis=-1) - 1.0)
        if np.any(norm_error > _BROAD_QUAT_NORM_TOL):
            sample = int(np.flatnonzero(~nan_rows)[np.argmax(norm_error)])
            raise ValueError(f"{label}: not a unit quaternion at sample {sample}")
        object.__setattr__(self, "quat_ref", self._frozen(quat))
        movement = np.asarray(self.movement)
        if movement.dtype != np.bool_ or movement.shape != (n,):
            raise ValueError(
                f"{where}: movement must be a boolean array of shape {(n,)}, got {movement.dtype} {movement.shape}"
            )
        object.__setattr__(self, "movement", self._frozen(movement))
        if not isinstance(self.info, str):
            raise ValueError(f"{where}: info must be a string")

    @staticmethod
    def _frozen(arr: np.ndarray) -> np.ndarray:
        arr = np.array(arr, copy=True)
        arr.setflags(write=False)
        return arr

    @property
    def n_samples(self) -> int:
        """Number of samples T."""
        return self.time_s.size

    @property
    def reference_valid(self) -> np.ndarray:
        """Boolean ``(T,)``: samples where the optical reference exists (not NaN)."""
        return ~np.isnan(self.quat_ref[:, 0])


def load_broad(trial, data_dir=None, *, download: bool = True, downloader=None) -> BroadTrial:
    """Load one BROAD trial (Laidig et al. 2021, CC BY 4.0), downloading and verifying it if needed.

    Parameters
    ----------
    trial : str or int
        Trial name as in :func:`broad_trials` (with or without ``.mat``), or its number
        (``2`` for ``"02_undisturbed_slow_rotation_B"``).
    data_dir : str or pathlib.Path, optional
        Folder of the files; default ``$WSNLIB_BROAD_DIR``, else ``<ROOT>/data/raw/broad``.
    download : bool
        Download a missing file (pooch, from the repository pinned to :data:`BROAD_COMMIT`).
    downloader : callable, optional
        Replaces pooch's HTTP downloader; see :func:`broad_file`.

    Returns
    -------
    BroadTrial
        Signals in the IMU body frame: ``gyr`` rad/s, ``acc`` m/s², ``mag`` µT, ``quat_ref``
        ``[w, x, y, z]`` body → ENU (NaN rows where the optical markers were lost),
        ``movement`` bool, at ``fs`` = 2000/7 ≈ 285.714 Hz.

    Raises
    ------
    ValueError
        Unknown trial (the message lists the known ones); SHA-256 mismatch (naming the file,
        the expected and the actual hash); a missing key, a wrong shape or non-finite IMU
        signals (naming the trial and the key).
    FileNotFoundError, OSError
        See :func:`broad_file`.
    """
    import scipy.io

    name = _broad_trial_name(trial)
    path = broad_file(f"{name}.mat", data_dir, download=download, downloader=downloader)
    mat = scipy.io.loadmat(path)
    missing = [key for key in ("imu_gyr", "imu_acc", "imu_mag", "opt_quat", "movement", "sampling_rate")
               if key not in mat]
    if missing:
        raise ValueError(f"BROAD trial {name!r} ({path}) lacks the key(s) {missing}")
    rate = np.asarray(mat["sampling_rate"], dtype=float)
    if rate.size != 1:
        raise ValueError(f"BROAD trial {name!r}: key 'sampling_rate' must be a scalar, got shape {rate.shape}")
    fs = float(rate.reshape(()))
    movement_raw = np.asarray(mat["movement"]).reshape(-1)
    if not np.all((movement_raw == 0) | (movement_raw == 1)):
        raise ValueError(f"BROAD trial {name!r}: key 'movement' must hold only 0 and 1")
    n_samples = np.asarray(mat["imu_gyr"]).shape[0]
    info = mat.get("info")
    info_text = str(np.asarray(info).reshape(-1)[0]) if info is not None and np.asarray(info).size else ""
    return BroadTrial(
        name=name,
        fs=fs,
        time_s=np.arange(n_samples) / check_positive(fs, f"BROAD trial {name!r}: sampling_rate"),
        gyr=mat["imu_gyr"],
        acc=mat["imu_acc"],
        mag=mat["imu_mag"],
        quat_ref=mat["opt_quat"],
        movement=movement_raw.astype(bool),
        info=info_text,
    )
