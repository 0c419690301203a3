"""Raw IMU recordings: the in-memory :class:`Recording` and its CSV + JSON file format, and the
sidecar writer/reader shared by every CSV + JSON format of :mod:`wsnlib.io`.

The CSV + JSON format is what the notebooks read, and the one a user converts real
recordings into.

File format (format version 2; version 1 is read too)
-----------------------------------------------------
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
quat_z                leaves them out).  Version 2: a row may leave all four cells empty
                      (or ``nan``) where the reference is missing (optical markers lost);
                      all four or none on a row.
movement      —       optional, version 2: ``1`` on the samples to score (the movement
                      phase, as BROAD's ``movement``), ``0`` elsewhere; per node.
============  ======  ===============================================================

Numbers are written with ``%.9g`` (9 significant digits), so writing the same recording
twice gives byte-identical files; reading back agrees within that precision (relative
≈ 5e-10).  Every value must be finite, except the reference cells of a row without reference;
the time stamps must be strictly increasing and the same for every node; missing samples are
not allowed (packet loss is applied later, as a mask, never by deleting rows).

**Versions.**  Version 2 adds missing-reference rows and the ``movement`` column to version 1;
a version-1 file means the same in version 2 and is read as before.  :func:`write_recording`
writes the oldest version that holds the recording: version 1, byte for byte what earlier
writers wrote, unless the recording has a movement mask or a missing reference row; then
version 2.  So a file that uses nothing new is still read by older readers, and the files the
notebooks write did not change.

**JSON sidecar** — an object with the keys

* ``format``: ``"wsnlib-recording"``; ``format_version``: ``1`` or ``2``;
* ``fs_hz``: nominal sampling rate (Hz);
* ``nodes``: list of node names, in row order;
* ``units``: ``{"time": "s", "gyr": "rad/s", "acc": "m/s^2", "mag": "uT"}``;
* ``frame_convention``: text describing the body and earth frames (informative);
* ``has_quaternions``: whether the CSV has the ``quat_*`` columns;
* ``has_movement`` (version 2 only): whether the CSV has the ``movement`` column;
* ``metadata``: free JSON object (generator, parameters, seed, subject, …);
* ``csv_rows``, ``csv_sha256``: the CSV's number of data rows and the SHA-256 of its bytes
  (written by every writer; a reader refuses a CSV that disagrees with them — a truncated or
  edited copy — and skips the check when a hand-made sidecar leaves both out).

Written with sorted keys and two-space indent; both files are written atomically (temporary
file, then rename).  If the sidecar is missing,
:func:`read_recording` infers ``fs`` from the median time step and the node order from the
first sample, and uses empty metadata (and reads both versions' columns).

The signal conventions are those of :mod:`wsnlib` (see ``wsnlib/__init__.py``).

The sidecar machinery all CSV + JSON formats share is :mod:`wsnlib.io.sidecar`.
"""


from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from wsnlib._user_warnings import warn_user
from wsnlib._validation import as_float_array, check_positive, check_type, real_array
from wsnlib.io.sidecar import (
    check_columns,
    check_names,
    finite_column,
    name_column,
    read_table,
    sidecar_path,
    write_table_with_sidecar,
)

FORMAT_NAME = "wsnlib-recording"
#: The version written when the recording needs it (a movement mask, a missing reference row).
FORMAT_VERSION = 2
#: Versions read besides :data:`FORMAT_VERSION`; the first is written when nothing newer is needed.
OLDER_VERSIONS = (1,)

#: Column names of the CSV, in order; the quaternion columns and ``movement`` are optional.
SIGNAL_COLUMNS: dict[str, tuple[str, str, str]] = {
    "gyr": ("gyr_x_rad_s", "gyr_y_rad_s", "gyr_z_rad_s"),
    "acc": ("acc_x_m_s2", "acc_y_m_s2", "acc_z_m_s2"),
    "mag": ("mag_x_uT", "mag_y_uT", "mag_z_uT"),
}
QUAT_COLUMNS: tuple[str, str, str, str] = ("quat_w", "quat_x", "quat_y", "quat_z")
BASE_COLUMNS: tuple[str, ...] = ("time_s", "node", *SIGNAL_COLUMNS["gyr"], *SIGNAL_COLUMNS["acc"],
                                 *SIGNAL_COLUMNS["mag"])
MOVEMENT_COLUMN = "movement"

#: Units written to (and required in) the sidecar.
UNITS = {"time": "s", "gyr": "rad/s", "acc": "m/s^2", "mag": "uT"}

FRAME_CONVENTION = (
    "Signals in the sensor body frame. quat_[wxyz] is a unit quaternion [w, x, y, z] rotating "
    "body-frame vectors into the earth frame ENU (x east, y north, z up): v_E = q v_B q*. "
    "acc is specific force (+g along earth z at rest)."
)

FLOAT_FORMAT = "%.9g"

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
        Ground-truth orientation (body → ENU), unit norm; None when unknown.  A row of four NaN
        marks a sample without reference (:attr:`reference_valid`); a row is never partly NaN.
    metadata : dict
        Free, JSON-serialisable provenance (generator, parameters, seed, …).
    movement : numpy.ndarray of bool, shape (N_nodes, T), or None
        Samples to score (the movement phase), per node; None when not given (a study then
        scores every sample with a reference).
    """

    fs: float
    time_s: np.ndarray
    nodes: tuple[str, ...]
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray
    quat_true: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)
    movement: np.ndarray | None = None

    def __post_init__(self):
        self.fs = check_positive(self.fs, "fs")
        self.time_s = as_float_array(self.time_s, "time_s")
        if self.time_s.ndim != 1:
            raise ValueError(f"time_s must be 1-D, got shape {self.time_s.shape}")
        if self.time_s.size > 1 and np.any(np.diff(self.time_s) <= 0.0):
            raise ValueError("time_s must be strictly increasing")
        self.nodes = check_names(self.nodes, "nodes")
        shape = (len(self.nodes), self.time_s.size)
        for name in ("gyr", "acc", "mag"):
            arr = as_float_array(getattr(self, name), name, last_dim=3)
            if arr.shape != shape + (3,):
                raise ValueError(f"{name} must have shape {shape + (3,)}, got {arr.shape}")
            setattr(self, name, arr)
        if self.quat_true is not None:
            quat = real_array(self.quat_true, "quat_true")
            if quat.shape != shape + (4,):
                raise ValueError(f"quat_true must have shape {shape + (4,)}, got {quat.shape}")
            missing = np.isnan(quat)
            partial = missing.any(axis=-1) & ~missing.all(axis=-1)
            if np.any(partial) or np.any(np.isinf(quat)):
                node, sample = np.argwhere(partial | np.isinf(quat).any(axis=-1))[0]
                raise ValueError(f"quat_true at node {int(node)}, sample {int(sample)} is "
                                 f"{quat[node, sample].tolist()}: a row must be four finite numbers, or four NaN "
                                 f"where the reference is missing")
            self.quat_true = quat
        if not isinstance(self.metadata, dict):
            raise ValueError(f"metadata must be a dict, got {type(self.metadata).__name__}")
        if self.movement is not None:
            movement = np.asarray(self.movement)
            if movement.dtype != np.bool_ or movement.shape != shape:
                raise ValueError(f"movement must be a boolean array of shape {shape}, got {movement.dtype} "
                                 f"{movement.shape}")
            self.movement = movement.copy()

    @property
    def n_samples(self) -> int:
        """Number of samples T."""
        return self.time_s.size

    @property
    def reference_valid(self) -> np.ndarray:
        """Boolean ``(N_nodes, T)``: samples whose reference orientation exists (finite rows of
        ``quat_true``); all False without ``quat_true``."""
        if self.quat_true is None:
            return np.zeros((len(self.nodes), self.n_samples), dtype=bool)
        return ~np.isnan(self.quat_true[..., 0])

    def node_index(self, node: str) -> int:
        """Position of ``node`` on the node axis; ``ValueError`` if absent."""
        try:
            return self.nodes.index(node)
        except ValueError:
            raise ValueError(f"node {node!r} is not in this recording {self.nodes}") from None


def _version_needed(recording: Recording) -> int:
    """The oldest format version that holds ``recording``: 1 unless it has a movement mask or a
    sample without reference (then 2)."""
    gaps = recording.quat_true is not None and not recording.reference_valid.all()
    return FORMAT_VERSION if recording.movement is not None or gaps else OLDER_VERSIONS[0]


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
        The CSV path.  Writing the same recording again gives byte-identical files.  The
        format version is the oldest that holds it: 1 (the bytes earlier writers wrote)
        unless the recording has a movement mask or samples without reference; a missing
        reference is written as four empty cells, the movement mask as ``0``/``1``.

    Raises
    ------
    ValueError
        If ``path`` ends in ``.json`` or the metadata is not JSON serialisable.
    """
    check_type(recording, Recording, "recording")
    n_nodes, n_samples = len(recording.nodes), recording.n_samples
    data: dict[str, object] = {"time_s": np.repeat(recording.time_s, n_nodes),
                               "node": np.tile(np.array(recording.nodes, dtype=object), n_samples)}
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
    if recording.movement is not None:
        frame[MOVEMENT_COLUMN] = np.swapaxes(recording.movement, 0, 1).reshape(-1).astype(np.int8)
    version = _version_needed(recording)
    sidecar = {"format": FORMAT_NAME, "format_version": version, "fs_hz": recording.fs,
               "nodes": list(recording.nodes), "units": UNITS, "frame_convention": FRAME_CONVENTION,
               "has_quaternions": recording.quat_true is not None, "metadata": recording.metadata}
    if version >= 2:
        sidecar["has_movement"] = recording.movement is not None
    return write_table_with_sidecar(frame, path, sidecar, FLOAT_FORMAT, what="recording.metadata")


def read_recording(path) -> Recording:
    """Read a recording written by :func:`write_recording` (or converted into its format).

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file, or its sidecar (``.json``: the CSV beside it is read); the sidecar
        ``path.with_suffix('.json')`` is read when present.  Format version 1 or 2.

    Returns
    -------
    Recording
        ``quat_true`` is None when the CSV has no ``quat_*`` columns, and holds rows of NaN
        where a version-2 file leaves the reference empty; ``movement`` is None without the
        ``movement`` column.  Quaternion norms must be within 1e-6 of 1; they are returned as
        read (not renormalised), so that reading and writing a file again reproduces it byte
        for byte.

    Raises
    ------
    ValueError
        Naming the file and the column: missing, unknown or misordered columns, only some
        ``quat_*`` columns, non-numeric or non-finite values (outside a row's empty reference),
        a reference row only partly empty, movement values other than 0 and 1, version-2
        content under a version-1 sidecar, unknown nodes, nodes with different time stamps or
        sample counts, time not strictly increasing, a time step that disagrees with the
        sidecar's ``fs_hz`` by more than 1 %, or a bad sidecar.
    """
    path = Path(path)
    if path.suffix.lower() == ".json":
        path = path.with_suffix(".csv")
    meta, frame = read_table(path, FORMAT_NAME, FORMAT_VERSION, what="a recording", required=False,
                             keys=("fs_hz", "nodes", "units"), units=UNITS, older_versions=OLDER_VERSIONS,
                             dtype={"node": str}, keep_default_na=False, na_values=[])
    if meta is not None:
        try:
            check_positive(meta["fs_hz"], "fs_hz")
            if not isinstance(meta["nodes"], list):
                raise ValueError("'nodes' must be a non-empty list of node names")
            nodes = check_names(meta["nodes"], "nodes")
        except ValueError as exc:
            raise ValueError(f"{sidecar_path(path)}: {exc}") from exc

    columns = list(frame.columns)
    quat_present = [c for c in QUAT_COLUMNS if c in columns]
    if quat_present and len(quat_present) != 4:
        absent = [c for c in QUAT_COLUMNS if c not in columns]
        raise ValueError(f"{path}: quaternion columns must come all four or none; missing {absent}")
    movement_present = MOVEMENT_COLUMN in columns
    expected = (list(BASE_COLUMNS) + (list(QUAT_COLUMNS) if quat_present else [])
                + ([MOVEMENT_COLUMN] if movement_present else []))
    check_columns(frame, expected, str(path))  # exactly these, in order, and at least one row
    version = FORMAT_VERSION if meta is None else meta["format_version"]
    for key, present, what in (("has_quaternions", quat_present, "the quat_* columns"),
                               ("has_movement", movement_present, f"the {MOVEMENT_COLUMN!r} column")):
        if meta is not None and bool(meta.get(key, bool(present))) != bool(present):
            raise ValueError(f"{sidecar_path(path)}: {key!r} is {meta.get(key)!r} "
                             f"but {path} {'has' if present else 'lacks'} {what}")
    if movement_present and version < 2:
        raise ValueError(f"{path}: the {MOVEMENT_COLUMN!r} column needs format_version 2, but "
                         f"{sidecar_path(path)} says {version}")

    numeric = {column: finite_column(frame, column, path) for column in BASE_COLUMNS if column != "node"}
    if quat_present:
        numeric.update(_reference_columns(frame, path, version))
    node_col = name_column(frame, "node", path)
    if meta is None:
        warn_user(f"{path}: no sidecar {sidecar_path(path).name}; fs and the node order are inferred, and a copy "
                  f"cut short at a row boundary cannot be told from a shorter recording (write_recording "
                  f"writes the sidecar with the row count and SHA-256)")
        nodes = tuple(dict.fromkeys(node_col))
    else:
        stray = sorted(set(node_col) - set(nodes))
        if stray:
            raise ValueError(f"{path}: column 'node' has node(s) {stray} not listed in the sidecar")

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
        raise ValueError(f"{path}: column 'node': rows must cycle through {list(nodes)} for every sample; "
                         f"data row {row + 1} has {node_col[row]!r}, expected {expected_nodes[row]!r}")

    time = numeric["time_s"].reshape(n_samples, n_nodes)
    if not np.all(time == time[:, :1]):
        row = int(np.argmax(np.any(time != time[:, :1], axis=1)))
        raise ValueError(f"{path}: column 'time_s': nodes have different time stamps at sample {row} "
                         f"({time[row].tolist()})")
    time_s = time[:, 0]
    if n_samples > 1 and np.any(np.diff(time_s) <= 0.0):
        row = int(np.argmax(np.diff(time_s) <= 0.0))
        raise ValueError(f"{path}: column 'time_s' is not strictly increasing at sample {row + 1}")

    if meta is not None:
        fs = float(meta["fs_hz"])
        if n_samples > 1:
            median_step = float(np.median(np.diff(time_s)))
            if not math.isclose(median_step, 1.0 / fs, rel_tol=0.01):
                raise ValueError(f"{path}: column 'time_s' has median step {median_step:.6g} s, which "
                                 f"disagrees with fs_hz = {fs:g} in {sidecar_path(path)}")
        metadata = dict(meta["metadata"])
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
        off = np.abs(norm - 1.0) > _QUAT_NORM_TOL  # False on rows without reference (NaN)
        if np.any(off):
            node, sample = np.argwhere(off)[0]
            raise ValueError(f"{path}: columns quat_*: not a unit quaternion (norm {norm[node, sample]:.9g}) "
                             f"for node {nodes[node]!r} at sample {sample}")
    movement = None
    if movement_present:
        movement = _movement_column(frame, path).reshape(n_samples, n_nodes).T.copy()

    return Recording(fs=fs, time_s=time_s.copy(), nodes=nodes, gyr=block(SIGNAL_COLUMNS["gyr"]),
                     acc=block(SIGNAL_COLUMNS["acc"]), mag=block(SIGNAL_COLUMNS["mag"]), quat_true=quat,
                     metadata=metadata, movement=movement)


#: Cells that mark a missing reference in the quat_* columns (version 2), compared in lower case.
_MISSING_CELLS = ("", "nan")


def _reference_columns(frame: pd.DataFrame, path: Path, version: int) -> dict[str, np.ndarray]:
    """The quat_* columns as floats, NaN where a row leaves all four empty (version 2), else
    ``ValueError`` naming the file, the column and the data row."""
    values, missing = {}, {}
    for column in QUAT_COLUMNS:
        text = frame[column].astype(str).str.strip().str.lower()
        missing[column] = text.isin(_MISSING_CELLS).to_numpy()
        if not missing[column].any():
            values[column] = finite_column(frame, column, path)
            continue
        parsed = pd.to_numeric(frame[column].where(~missing[column]), errors="coerce").to_numpy(dtype=float)
        bad = ~missing[column] & ~np.isfinite(parsed)
        if np.any(bad):
            row = int(np.argmax(bad))
            raise ValueError(f"{path}: column {column!r} has a non-numeric or non-finite value "
                             f"{frame[column].iloc[row]!r} at data row {row + 1}")
        values[column] = parsed
    stacked = np.stack(list(missing.values()), axis=-1)
    if stacked.any() and version < 2:
        row = int(np.argmax(stacked.any(axis=-1)))
        raise ValueError(f"{path}: data row {row + 1} has no reference (empty quat_* cells), which needs "
                         f"format_version 2, but {sidecar_path(path)} says {version}")
    partial = stacked.any(axis=-1) & ~stacked.all(axis=-1)
    if np.any(partial):
        row = int(np.argmax(partial))
        empty = [c for c in QUAT_COLUMNS if missing[c][row]]
        raise ValueError(f"{path}: columns quat_*: data row {row + 1} leaves {empty} empty but not all four "
                         f"(a missing reference leaves all four empty)")
    return values


def _movement_column(frame: pd.DataFrame, path: Path) -> np.ndarray:
    """The movement column as bool (cells ``0`` or ``1``), else ``ValueError`` naming file and data row."""
    text = frame[MOVEMENT_COLUMN].astype(str).str.strip()
    bad = ~text.isin(("0", "1")).to_numpy()
    if np.any(bad):
        row = int(np.argmax(bad))
        raise ValueError(f"{path}: column {MOVEMENT_COLUMN!r} must hold 0 or 1, got "
                         f"{frame[MOVEMENT_COLUMN].iloc[row]!r} at data row {row + 1}")
    return (text == "1").to_numpy()
