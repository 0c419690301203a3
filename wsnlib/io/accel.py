"""Accelerometer and Kinect sample tables of paper 002's testbed: a long CSV + JSON format.

The companions of the RSS recordings of :mod:`wsnlib.io.rss`, on the same clock: what each
target node's accelerometer reported (paper 002, Sec. 4.1: sampled at 100 Hz, down-sampled
to 30 Hz, time-stamped with the base station's clock) and where a Kinect skeletal tracker
put each target (Sec. 4.1: ~30 fps, targets derived from the arm joints).  The simulator
(:func:`wsnlib.sim.campaign.simulate_dynamic_campaign`) writes them; a real testbed's logs
are converted into them (one row per sample and target).

File format (format version 1)
------------------------------
A table is two files side by side: ``<name>.csv`` and ``<name>.json`` (the sidecar), as in
:mod:`wsnlib.io.rss`.  The sidecar's ``kind`` says which table it is: ``"acc"`` or ``"kinect"``.

**CSV** — comma separated, UTF-8, ``\\n`` line ends, one header line, then one row per
(sample, target).  Columns, exactly these names in this order:

============  =====  ==========================================================================
column        unit   meaning
============  =====  ==========================================================================
time_s        s      the sample's time stamp on the session clock shared with the RSS packets
                     (accelerometer: end of the 1/30 s window the sample summarises; Kinect:
                     the frame time)
user          —      user name
session       —      session name (e.g. ``online_dynamic``)
target        —      target node, one of the sidecar's ``targets`` (``T1``, ``T2``)
label         —      what the arm was doing at ``time_s`` (posture, ``M1_…``, ``transition``)
============  =====  ==========================================================================

then, for ``kind = "acc"``:

============  =====  ==========================================================================
acc_x_m_s2    m/s²   accelerometer reading (specific force: +g upwards at rest) along the
acc_y_m_s2           device's x, y, z axes.  Device frame: the segment frame of
acc_z_m_s2           :mod:`wsnlib.sim.body` (x along the segment, distal) unless the sidecar's
                     metadata says otherwise.
============  =====  ==========================================================================

and for ``kind = "kinect"``:

============  =====  ==========================================================================
kinect_x_m    m      target position as derived from the Kinect's tracked joints, shoulder
kinect_y_m           frame (origin at the right shoulder joint, x to the user's right,
kinect_z_m           y forward, z up; paper 002, Table 1 and footnote 4)
============  =====  ==========================================================================

Text fields must be non-empty, without commas, quotes, line breaks or surrounding spaces.
Floats are rounded to six decimals and written with ``%.6f`` (−0 as 0), so writing the same
table twice — or writing what :func:`read_samples` returned — gives byte-identical files.
Rows are grouped in contiguous blocks per (user, session) in order of first appearance and
ordered by time, then target (sidecar order) inside a block; the writer sorts them so.  A
(user, session, target, time_s) appears at most once.  A sample that was never received is
an absent row.

**JSON sidecar** — an object with the keys ``format`` (``"wsnlib-samples"``),
``format_version`` (1), ``kind``, ``rate_hz`` (nominal samples per second per target),
``targets`` (names, in order), ``units`` (exactly :data:`UNITS` of the kind: a reader refuses
any other unit — convert the data first), ``frame`` (informative text), ``metadata`` (free
JSON object: sensor spec, camera placement, seed …), ``csv_rows`` and ``csv_sha256`` (the
CSV's data rows and SHA-256: a truncated or edited CSV is refused; a hand-made sidecar may
leave both out).  Written with sorted keys and two-space indent; both files are written
atomically.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from wsnlib._validation import check_choice, check_positive, check_type
from wsnlib.io.sidecar import (
    check_columns,
    check_names,
    check_order,
    check_sidecar_units,
    finite_column,
    name_column,
    read_table,
    sidecar_path,
    sort_rows,
    write_table_with_sidecar,
)
from wsnlib.testbed import TARGET_NAMES

FORMAT_NAME = "wsnlib-samples"
FORMAT_VERSION = 1

#: Leading columns of every kind.
KEY_COLUMNS: tuple[str, ...] = ("time_s", "user", "session", "target", "label")
TEXT_COLUMNS: tuple[str, ...] = ("user", "session", "target", "label")

#: Value columns of each kind, in order.
VALUE_COLUMNS: dict[str, tuple[str, str, str]] = {
    "acc": ("acc_x_m_s2", "acc_y_m_s2", "acc_z_m_s2"),
    "kinect": ("kinect_x_m", "kinect_y_m", "kinect_z_m"),
}
KINDS: tuple[str, ...] = tuple(VALUE_COLUMNS)

#: Printf format of the float columns.
FLOAT_FORMAT = "%.6f"

UNITS = {
    "acc": {"time": "s", "acc": "m/s^2 (specific force)"},
    "kinect": {"time": "s", "position": "m"},
}

FRAMES = {
    "acc": (
        "Device frame of each target node: by default the segment frame of wsnlib.sim.body (x along the "
        "segment, pointing distally; z dorsal), specific force (+g upwards at rest)."
    ),
    "kinect": (
        "Shoulder frame: origin at the right shoulder joint, x to the user's right, y forward, z up "
        "(right-handed; ENU for a user facing north). Paper 002 (Giuberti et al.), Table 1 and footnote 4."
    ),
}


def columns(kind: str) -> tuple[str, ...]:
    """CSV columns of ``kind`` ("acc" or "kinect"), in order."""
    return KEY_COLUMNS + VALUE_COLUMNS[check_choice(kind, "kind", KINDS)]


def _validate(df, kind: str, targets, where: str) -> pd.DataFrame:
    """Check and normalise a sample table; errors name ``where`` and the column."""
    check_columns(df, columns(kind), where)
    out = {column: finite_column(df, column, where) for column in ("time_s",) + VALUE_COLUMNS[kind]}
    out.update({column: name_column(df, column, where) for column in TEXT_COLUMNS})
    stray = sorted(set(out["target"]) - set(targets))
    if stray:
        raise ValueError(f"{where}: column 'target' has target(s) {stray} not in the sidecar's targets {list(targets)}")
    return pd.DataFrame({c: out[c] for c in columns(kind)})


def write_samples(df: pd.DataFrame, path, kind: str, metadata: dict | None = None, *, rate_hz: float | None = None,
                  targets=TARGET_NAMES) -> Path:
    """Write a sample table as ``path`` (CSV) and its sidecar ``path.with_suffix('.json')``.

    Parameters
    ----------
    df : pandas.DataFrame
        Columns :func:`columns` ``(kind)``.
    path : str or pathlib.Path
        CSV file (parent folders are created).
    kind : {"acc", "kinect"}
    metadata : dict, optional
        Free JSON-serialisable provenance.
    rate_hz : float, optional
        Nominal samples per second per target; default ``df.attrs["rate_hz"]``; required one
        way or the other.
    targets : sequence of str
        Target names allowed, in order (default T1, T2).

    Returns
    -------
    pathlib.Path
        The CSV path.  Writing the same table again gives byte-identical files.
    """
    kind = check_choice(kind, "kind", KINDS)
    targets = check_names(targets, "targets")
    where = f"{kind} table for {path}"
    rate = rate_hz if rate_hz is not None else (getattr(df, "attrs", {}) or {}).get("rate_hz")
    if rate is None:
        raise ValueError(f"{where}: rate_hz is required (argument or df.attrs['rate_hz'])")
    rate = check_positive(rate, "rate_hz")
    metadata = check_type({} if metadata is None else metadata, dict, "metadata")
    frame = sort_rows(_validate(df, kind, targets, where), {"target": targets})
    check_order(frame, {"target": targets}, where, "sample of one target at one time")
    for column in ("time_s",) + VALUE_COLUMNS[kind]:
        frame[column] = np.round(frame[column].to_numpy(dtype=float), 6) + 0.0  # -0.0 prints as 0
    sidecar = {"format": FORMAT_NAME, "format_version": FORMAT_VERSION, "kind": kind, "rate_hz": rate,
               "targets": list(targets), "units": UNITS[kind], "frame": FRAMES[kind], "metadata": metadata}
    return write_table_with_sidecar(frame, path, sidecar, FLOAT_FORMAT)


def read_samples(path, kind: str | None = None) -> tuple[pd.DataFrame, dict]:
    """Read a sample table written by :func:`write_samples` (or converted into its format).

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file; its sidecar must exist.
    kind : {"acc", "kinect"}, optional
        Expected kind; default whatever the sidecar says.

    Returns
    -------
    df : pandas.DataFrame
        Columns :func:`columns` ``(kind)``; floats float64, names ``object``; ``df.attrs``
        holds ``rate_hz`` and ``kind``, so ``write_samples(df, other, kind, sidecar["metadata"])``
        reproduces the files byte for byte.
    sidecar : dict

    Raises
    ------
    ValueError
        Naming the file and column or the sidecar: bad columns or values, rows out of order,
        a sidecar of another kind, units other than :data:`UNITS` of the kind, a row count or
        SHA-256 that disagrees with the CSV (a truncated or edited copy).
    """
    meta, raw = read_table(path, FORMAT_NAME, FORMAT_VERSION, what="a sample table")
    side = sidecar_path(path)
    if meta.get("kind") not in VALUE_COLUMNS:
        raise ValueError(f"{side}: 'kind' must be one of {KINDS}, got {meta.get('kind')!r}")
    if kind is not None and meta["kind"] != check_choice(kind, "kind", KINDS):
        raise ValueError(f"{side}: holds a {meta['kind']!r} table, expected {kind!r}")
    check_sidecar_units(meta, UNITS[meta["kind"]], side)
    try:
        meta["rate_hz"] = check_positive(meta.get("rate_hz"), "rate_hz")
        meta["targets"] = list(check_names(meta.get("targets", ()), "targets"))
    except ValueError as exc:
        raise ValueError(f"{side}: {exc}") from exc
    frame = _validate(raw, meta["kind"], meta["targets"], str(path))
    check_order(frame, {"target": meta["targets"]}, path, "sample of one target at one time")
    frame.attrs = {"rate_hz": meta["rate_hz"], "kind": meta["kind"]}
    return frame, meta


def write_acc(df: pd.DataFrame, path, metadata: dict | None = None, *, rate_hz: float | None = None) -> Path:
    """:func:`write_samples` with ``kind="acc"``."""
    return write_samples(df, path, "acc", metadata, rate_hz=rate_hz)


def read_acc(path) -> tuple[pd.DataFrame, dict]:
    """:func:`read_samples` of an ``"acc"`` table."""
    return read_samples(path, "acc")


def write_kinect(df: pd.DataFrame, path, metadata: dict | None = None, *, rate_hz: float | None = None) -> Path:
    """:func:`write_samples` with ``kind="kinect"``."""
    return write_samples(df, path, "kinect", metadata, rate_hz=rate_hz)


def read_kinect(path) -> tuple[pd.DataFrame, dict]:
    """:func:`read_samples` of a ``"kinect"`` table."""
    return read_samples(path, "kinect")
