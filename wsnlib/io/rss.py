"""RSS recordings of body-area fingerprinting (paper 002): the long CSV + JSON format, and
fingerprint vectors.

This is the format the simulator (:mod:`wsnlib.sim.radio`) writes and the one a real
testbed's logs are converted into: each anchor that receives a target's packet reports one
RSS value, and every report becomes one row.

File format (format version 1)
------------------------------
A recording is two files side by side: ``<name>.csv`` and ``<name>.json`` (the sidecar).
:func:`write_rss` writes both; :func:`read_rss` reads and checks them.

**CSV** — comma separated, UTF-8, ``\\n`` line ends, one header line, then one row per
received (packet, anchor).  Columns, exactly these names in this order:

=========  =====  ===========================================================================
column     unit   meaning
=========  =====  ===========================================================================
time_s     s      the packet's time stamp (the target's clock, synchronised with the base
                  station; paper 002, Sec. 4.1).  Identical in every row of the same packet:
                  rows with equal (user, session, target, time_s) are one packet.
user       —      user name
session    —      session name (e.g. ``training``, ``online_static``, ``online_dynamic``)
target     —      transmitting target, one of the sidecar's ``targets``
anchor     —      receiving anchor, one of the sidecar's ``anchors``
rss_dbm    dBm    received signal strength, an integer (written without a decimal point)
label      —      what the arm was doing: a posture (``P1`` … ``P5``), a movement
                  (``M1_lower_P2_P3_P1`` …) or ``transition``
x_m        m      true position of the target (ground truth), shoulder frame: origin at the
y_m               right shoulder joint, x to the user's right, y forward, z up.  Identical in
z_m               every row of the same packet.
=========  =====  ===========================================================================

Text fields must be non-empty, without commas, quotes or line breaks.  Floats are rounded to
six decimals and written with ``%.6f`` (µs and µm; −0 is written as 0), ``rss_dbm`` as an integer, so writing the same
table twice — or writing what :func:`read_rss` returned — gives byte-identical files.
Rows are grouped in contiguous blocks per (user, session); inside a block they are ordered
by time, then target, then anchor (sidecar orders); :func:`write_rss` sorts them so.
Packets received by no anchor leave no row (a lost reading is an absent row, not a NaN).

**JSON sidecar** — an object with the keys

* ``format``: ``"wsnlib-rss"``; ``format_version``: ``1``;
* ``packet_rate_hz``: nominal packets per second per target;
* ``anchors``, ``targets``: lists of names (the column orders of fingerprint vectors);
* ``anchor_positions_m``: ``{user: {session: {anchor: [x, y, z]}}}`` in m, shoulder frame,
  or ``{}`` when not surveyed (informative: fingerprinting does not need them);
* ``units``: exactly ``{"time": "s", "rss": "dBm", "position": "m"}`` (:data:`UNITS`; a
  reader refuses any other unit — convert the data first); ``frame``: informative text;
* ``metadata``: free JSON object (generator, seed, user parameters, channel parameters …);
* ``csv_rows``, ``csv_sha256``: the CSV's data rows and SHA-256, checked by :func:`read_rss`
  (a truncated or edited CSV is refused; a hand-made sidecar may leave both out).

Written with sorted keys and two-space indent; both files are written atomically.  The
sidecar is required; its machinery is :mod:`wsnlib.io.sidecar`.  The writer and the reader
apply the same checks to the table (:func:`validate_table`: columns, types, names, values;
:func:`check_rows`: order, uniqueness, per-packet consistency); errors name the file or
table, the column and the data row.

Fingerprint vectors
-------------------
:func:`rss_vectors` turns the long table into one vector of the anchors' RSS per packet of a
target (or per window of ``window_packets`` consecutive packets, of ``window_s`` seconds, or
per posture hold), with NaN where an anchor reported nothing, and the vector's label and true
position.  It is a thin wrapper: the vector type (:class:`~wsnlib.io.vectors.RssVectors`)
and the windowing (:func:`~wsnlib.io.vectors.window_readings`) are those of
:mod:`wsnlib.io.vectors`, shared with the PABR loader.  The fingerprint estimators take NaN
in training vectors as a missing reading but refuse it online; ``fill="last"`` carries each
anchor's previous reading forward within the session (a causal hold, as an online system
would), and a constant floor fills what was never received.
"""


from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd

from wsnlib._validation import check_count, check_positive, check_type
from wsnlib.io.sidecar import (
    block_order,
    check_columns,
    check_names,
    check_order,
    finite_column,
    name_column,
    read_table,
    sidecar_path,
    sort_rows,
    write_table_with_sidecar,
)
from wsnlib.io.vectors import RssVectors, window_readings
from wsnlib.testbed import ANCHOR_NAMES, TARGET_NAMES

FORMAT_NAME = "wsnlib-rss"
FORMAT_VERSION = 1

#: Printf format of the float columns.
FLOAT_FORMAT = "%.6f"

#: Default floor (dBm) for anchors that never reported: the CC2420's sensitivity (−95 dBm,
#: see :mod:`wsnlib.sim.radio`).
DEFAULT_FLOOR_DBM = -95.0

UNITS = {"time": "s", "rss": "dBm", "position": "m"}

FRAME = (
    "Positions in the shoulder frame: origin at the right shoulder joint, x to the user's right, "
    "y forward, z up (right-handed; ENU for a user facing north). Paper 002 (Giuberti et al.), "
    "Table 1 and footnote 4."
)


# --------------------------------------------------------------------------------------------
# The long table: columns and the checks every reader and writer applies
# --------------------------------------------------------------------------------------------

#: CSV columns, in order.
COLUMNS: tuple[str, ...] = ("time_s", "user", "session", "target", "anchor", "rss_dbm", "label", "x_m", "y_m", "z_m")
TEXT_COLUMNS: tuple[str, ...] = ("user", "session", "target", "anchor", "label")
FLOAT_COLUMNS: tuple[str, ...] = ("time_s", "x_m", "y_m", "z_m")

#: Plausible range of an IEEE 802.15.4 RSS report (dBm): the CC2420's RSSI register is an
#: 8-bit signed value with an offset of about −45 dB, so readings lie far inside it.
RSS_RANGE_DBM: tuple[int, int] = (-128, 20)

_INT_RE = re.compile(r"^-?\d+$")


def validate_table(df: pd.DataFrame, anchors, targets, where: str) -> pd.DataFrame:
    """Check and normalise a long RSS table; errors name ``where`` and the column."""
    check_columns(df, COLUMNS, where)
    out = {column: finite_column(df, column, where) for column in FLOAT_COLUMNS}
    rss = df["rss_dbm"]
    if pd.api.types.is_integer_dtype(rss.dtype):
        rss_values = rss.to_numpy(dtype=np.int64)
    else:
        if rss.dtype == object:
            text = rss.astype(str)
            bad = ~text.str.match(_INT_RE).to_numpy()
        else:
            values = pd.to_numeric(rss, errors="coerce").to_numpy(dtype=float)
            bad = ~np.isfinite(values) | (values != np.round(values))
        if np.any(bad):
            row = int(np.argmax(bad))
            raise ValueError(f"{where}: column 'rss_dbm' must hold integers, got {rss.iloc[row]!r} at data row "
                             f"{row + 1}")
        rss_values = text.astype(np.int64).to_numpy() if rss.dtype == object else values.astype(np.int64)
    lo, hi = RSS_RANGE_DBM
    bad = (rss_values < lo) | (rss_values > hi)
    if np.any(bad):
        row = int(np.argmax(bad))
        raise ValueError(f"{where}: column 'rss_dbm' value {rss_values[row]} at data row {row + 1} is outside "
                         f"[{lo}, {hi}] dBm")
    out["rss_dbm"] = rss_values
    for column in TEXT_COLUMNS:
        out[column] = name_column(df, column, where)
    for column, allowed, what in (("anchor", anchors, "anchors"), ("target", targets, "targets")):
        stray = sorted(set(out[column]) - set(allowed))
        if stray:
            raise ValueError(f"{where}: column {column!r} has {what[:-1]}(s) {stray} not in the sidecar's {what} "
                             f"{list(allowed)}")
    return pd.DataFrame({c: out[c] for c in COLUMNS})


def check_rows(frame: pd.DataFrame, anchors, targets, where: str) -> None:
    """Order, uniqueness and per-packet consistency of a table (:func:`wsnlib.io.sidecar.check_order`)."""
    packet = check_order(frame, {"target": targets, "anchor": anchors}, where, "report of one packet by one anchor")
    for column in ("label", "x_m", "y_m", "z_m"):
        values = frame[column].to_numpy()
        differs = packet & (values[1:] != values[:-1])
        if np.any(differs):
            row = int(np.argmax(differs)) + 1
            raise ValueError(f"{where}: column {column!r} differs between rows of the same packet at data row "
                             f"{row + 1}")


# --------------------------------------------------------------------------------------------
# Writer / reader
# --------------------------------------------------------------------------------------------


def write_rss(df: pd.DataFrame, path, metadata: dict | None = None, *, packet_rate_hz: float | None = None,
              anchor_positions_m: dict | None = None, anchors=ANCHOR_NAMES, targets=TARGET_NAMES) -> Path:
    """Write the long RSS table ``df`` as ``path`` (CSV) and its sidecar ``path.with_suffix('.json')``.

    Parameters
    ----------
    df : pandas.DataFrame
        Columns :data:`COLUMNS` (as :func:`wsnlib.sim.radio.simulate_rss` returns).
    path : str or pathlib.Path
        CSV file (parent folders are created).
    metadata : dict, optional
        Free JSON-serialisable provenance (seed, user parameters, …).
    packet_rate_hz : float, optional
        Default ``df.attrs["packet_rate_hz"]``; required one way or the other.
    anchor_positions_m : dict, optional
        ``{user: {session: {anchor: [x, y, z]}}}``; default ``df.attrs.get(...)`` or ``{}``.
    anchors, targets : sequence of str
        Names allowed in the table, in vector order (default A1…A7, T1, T2).

    Returns
    -------
    pathlib.Path
        The CSV path.  Writing the same table again gives byte-identical files.

    Raises
    ------
    ValueError
        Bad columns, values or names (naming the column), duplicate or inconsistent packet
        rows, a missing packet rate, metadata that is not JSON.
    """
    anchors = check_names(anchors, "anchors")
    targets = check_names(targets, "targets")
    where = f"table for {path}"
    attrs = getattr(df, "attrs", {}) or {}
    rate = packet_rate_hz if packet_rate_hz is not None else attrs.get("packet_rate_hz")
    if rate is None:
        raise ValueError(f"{where}: packet_rate_hz is required (argument or df.attrs['packet_rate_hz'])")
    rate = check_positive(rate, "packet_rate_hz")
    positions = anchor_positions_m if anchor_positions_m is not None else attrs.get("anchor_positions_m", {})
    positions = _check_positions(positions, anchors, where)
    metadata = check_type({} if metadata is None else metadata, dict, "metadata")

    frame = sort_rows(validate_table(df, anchors, targets, where), {"target": targets, "anchor": anchors})
    check_rows(frame, anchors, targets, where)
    # Round first and add 0.0 so that -0.0 and tiny negatives print as 0.000000.
    text = frame.copy()
    for c in FLOAT_COLUMNS:
        text[c] = np.round(text[c].to_numpy(dtype=float), 6) + 0.0
    text["rss_dbm"] = text["rss_dbm"].astype(np.int64)
    sidecar = {"format": FORMAT_NAME, "format_version": FORMAT_VERSION, "packet_rate_hz": rate,
               "anchors": list(anchors), "targets": list(targets), "anchor_positions_m": positions, "units": UNITS,
               "frame": FRAME, "metadata": metadata}
    return write_table_with_sidecar(text, path, sidecar, FLOAT_FORMAT)


def _check_positions(positions, anchors, where: str) -> dict:
    if not isinstance(positions, dict):
        raise ValueError(f"{where}: anchor_positions_m must be a dict {{user: {{session: {{anchor: [x, y, z]}}}}}}")
    out = {}
    for user, sessions in positions.items():
        if not isinstance(sessions, dict):
            raise ValueError(f"{where}: anchor_positions_m[{user!r}] must map sessions to anchor positions")
        out[str(user)] = {}
        for session, table in sessions.items():
            if not isinstance(table, dict):
                raise ValueError(f"{where}: anchor_positions_m[{user!r}][{session!r}] must map anchors to [x, y, z]")
            stray = sorted(set(table) - set(anchors))
            if stray:
                raise ValueError(f"{where}: anchor_positions_m[{user!r}][{session!r}] has unknown anchor(s) {stray}")
            entry = {}
            for anchor, xyz in table.items():
                arr = np.asarray(xyz, dtype=float)
                if arr.shape != (3,) or not np.all(np.isfinite(arr)):
                    raise ValueError(f"{where}: anchor_positions_m[{user!r}][{session!r}][{anchor!r}] must be 3 finite "
                                     f"numbers")
                entry[anchor] = [float(v) for v in arr]
            out[str(user)][str(session)] = entry
    return out


def read_rss(path) -> tuple[pd.DataFrame, dict]:
    """Read an RSS recording written by :func:`write_rss` (or converted into its format).

    Parameters
    ----------
    path : str or pathlib.Path
        The CSV file; its sidecar ``path.with_suffix('.json')`` must exist.

    Returns
    -------
    df : pandas.DataFrame
        Columns :data:`COLUMNS`; ``rss_dbm`` int64, the float columns float64, names as
        ``object``.  ``df.attrs`` holds ``packet_rate_hz`` and ``anchor_positions_m``, so
        that ``write_rss(df, other, sidecar["metadata"])`` reproduces the files byte for
        byte.
    sidecar : dict
        The sidecar object (``packet_rate_hz``, ``anchors``, ``targets``,
        ``anchor_positions_m``, ``metadata``, …).

    Raises
    ------
    ValueError
        Naming the file and the column: missing/unknown/misordered columns, non-numeric,
        non-finite or non-integer values, empty names, anchors or targets not in the sidecar,
        rows out of order, duplicated or inconsistent packets, or a bad sidecar (units other
        than :data:`UNITS`; a row count or SHA-256 that disagrees with the CSV).
    """
    path = Path(path)
    meta, raw = read_table(path, FORMAT_NAME, FORMAT_VERSION, what="an RSS recording",
                           keys=("packet_rate_hz", "anchors", "targets"), units=UNITS)
    try:
        meta["packet_rate_hz"] = check_positive(meta["packet_rate_hz"], "packet_rate_hz")
        meta["anchors"] = list(check_names(meta["anchors"], "anchors"))
        meta["targets"] = list(check_names(meta["targets"], "targets"))
        meta["anchor_positions_m"] = _check_positions(meta.get("anchor_positions_m", {}), meta["anchors"],
                                                      str(sidecar_path(path)))
    except ValueError as exc:
        raise ValueError(f"{sidecar_path(path)}: {exc}") from exc
    frame = validate_table(raw, meta["anchors"], meta["targets"], str(path))
    check_rows(frame, meta["anchors"], meta["targets"], str(path))
    frame.attrs = {"packet_rate_hz": meta["packet_rate_hz"], "anchor_positions_m": meta["anchor_positions_m"]}
    return frame, meta


# --------------------------------------------------------------------------------------------
# Fingerprint vectors
# --------------------------------------------------------------------------------------------


def rss_vectors(df: pd.DataFrame, window_packets: int | None = None, *, window_s: float | None = None,
                window: str | None = None, anchors=None, target: str | None = None, fill: str | float | None = None,
                floor_dbm: float = DEFAULT_FLOOR_DBM) -> RssVectors:
    """Fingerprint vectors (:class:`~wsnlib.io.vectors.RssVectors`) from a long RSS table.

    Packets are identified by (user, session, target, time_s).  Within each (user, session,
    target), consecutive packets with the same label form a point (a posture held, a
    movement); each point is cut into windows by :func:`wsnlib.io.vectors.window_readings`
    (the windowing the PABR path shares): by default one vector per packet.  A window's
    vector holds, per anchor, the mean of the readings received in it, NaN where none.

    Parameters
    ----------
    df : pandas.DataFrame
        Long table (:data:`COLUMNS`), e.g. from :func:`read_rss` or the simulator.
    window_packets : int, optional
        Packets per vector (default 1 = one vector per packet, unless ``window_s`` or
        ``window`` is given); the last window of a point may be shorter.
    window_s : float, optional
        Time windows of this length (s) from each point's first packet instead.
    window : {"point"}, optional
        One vector per point (each anchor's mean over the whole posture hold) instead.
    anchors : sequence of str, optional
        Vector columns; default :data:`wsnlib.testbed.ANCHOR_NAMES` (the table's anchors
        must be among them).
    target : str, optional
        Keep only this target; a target with no packets in ``df`` is a ``ValueError``.
    fill : None, "last", "floor" or float
        What replaces a missing reading (:mod:`wsnlib.io.vectors`): None keeps NaN
        (training vectors); ``"last"`` carries the anchor's last value forward within the
        (user, session, target), ``floor_dbm`` before its first reading; ``"floor"`` puts
        ``floor_dbm`` everywhere; a number puts that value (dBm).
    floor_dbm : float
        The "not heard" level (default −95 dBm, the receiver sensitivity).

    Returns
    -------
    RssVectors
        Ordered by (user, session) in order of appearance, target, time.  Packets that no
        anchor received have no rows and so no vector.
    """
    if window_packets is None and window_s is None and window is None:
        window_packets = 1
    if window_packets is not None:
        check_count(window_packets, "window_packets")
    anchors = ANCHOR_NAMES if anchors is None else check_names(anchors, "anchors")
    if isinstance(df, pd.DataFrame) and "target" in df.columns and len(df):
        targets = tuple(dict.fromkeys([*TARGET_NAMES, *df["target"].astype(str)]))
    else:
        targets = TARGET_NAMES
    frame = validate_table(df, anchors, targets, "rss_vectors table")
    if target is not None:
        present = list(dict.fromkeys(frame["target"].astype(str)))
        if target not in present:
            raise ValueError(f"target {target!r} has no packets in the rss_vectors table; its targets are {present}")
        frame = frame[frame["target"] == target].reset_index(drop=True)
    if len(frame):  # streams (user, session) in order of appearance, then target, then time
        block = block_order(frame)
        t_rank = frame["target"].map({t: i for i, t in enumerate(targets)}).to_numpy()
        frame = frame.iloc[np.lexsort((frame["time_s"].to_numpy(), t_rank, block))]
    readings = frame.assign(packet=frame["time_s"].to_numpy())
    return window_readings(readings, anchors, window_packets=window_packets, window_s=window_s, window=window,
                           fill=fill, floor_dbm=floor_dbm)
