"""The long RSS table of paper 002 (one row per received (packet, anchor)): its columns and
the checks every reader and writer of it applies.

:func:`validate_table` checks and normalises a table (columns, types, names, values);
:func:`check_rows` its order, uniqueness and per-packet consistency; :func:`sort_rows` puts it
in the file order of :mod:`wsnlib.io.rss` (the file format, whose docstring documents every
column).  Errors name the file or table, the column and the data row.
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd

from wsnlib.io.sidecar import finite_column

#: CSV columns, in order.
COLUMNS: tuple[str, ...] = ("time_s", "user", "session", "target", "anchor", "rss_dbm", "label", "x_m", "y_m", "z_m")
TEXT_COLUMNS: tuple[str, ...] = ("user", "session", "target", "anchor", "label")
FLOAT_COLUMNS: tuple[str, ...] = ("time_s", "x_m", "y_m", "z_m")

#: Plausible range of an IEEE 802.15.4 RSS report (dBm): the CC2420's RSSI register is an
#: 8-bit signed value with an offset of about −45 dB, so readings lie far inside it.
RSS_RANGE_DBM: tuple[int, int] = (-128, 20)

_INT_RE = re.compile(r"^-?\d+$")


def check_name(value, what: str) -> str:
    """``value`` if it is a usable name (non-empty, no commas, quotes or surrounding spaces), else ``ValueError``."""
    if not isinstance(value, str) or not value or value != value.strip() or any(c in value for c in ',"\n\r'):
        raise ValueError(
            f"{what} must be a non-empty string without commas, quotes or surrounding spaces, got {value!r}"
        )
    return value


def check_names(values, what: str) -> tuple[str, ...]:
    """``values`` as a tuple of unique usable names (at least one), else ``ValueError`` naming ``what``."""
    if isinstance(values, str):
        raise ValueError(f"{what} must be a list of names, not a single string")
    values = tuple(values)
    if not values:
        raise ValueError(f"{what} must name at least one entry")
    for v in values:
        check_name(v, f"entries of {what}")
    if len(set(values)) != len(values):
        raise ValueError(f"{what} must be unique, got {list(values)}")
    return values


def validate_table(df: pd.DataFrame, anchors, targets, where: str) -> pd.DataFrame:
    """Check and normalise a long RSS table; errors name ``where`` and the column."""
    if not isinstance(df, pd.DataFrame):
        raise ValueError(f"{where}: expected a pandas DataFrame, got {type(df).__name__}")
    columns = list(df.columns)
    missing = [c for c in COLUMNS if c not in columns]
    if missing:
        raise ValueError(f"{where}: missing column(s) {missing}; expected {list(COLUMNS)}")
    unknown = [c for c in columns if c not in COLUMNS]
    if unknown:
        raise ValueError(f"{where}: unknown column(s) {unknown}; expected {list(COLUMNS)}")
    if columns != list(COLUMNS):
        raise ValueError(f"{where}: columns must be in the order {list(COLUMNS)}, got {columns}")
    if len(df) == 0:
        raise ValueError(f"{where}: has no data rows")
    out = {}
    for column in FLOAT_COLUMNS:
        out[column] = finite_column(df, column, where)
    rss = df["rss_dbm"]
    if rss.dtype == object:
        text = rss.astype(str)
        bad = ~text.str.match(_INT_RE)
        if bad.any():
            row = int(np.argmax(bad.to_numpy()))
            raise ValueError(
                f"{where}: column 'rss_dbm' must hold integers, got {rss.iloc[row]!r} at data row {row + 1}"
            )
        rss_values = text.astype(np.int64).to_numpy()
    elif pd.api.types.is_integer_dtype(rss.dtype):
        rss_values = rss.to_numpy(dtype=np.int64)
    else:
        values = pd.to_numeric(rss, errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(values) | (values != np.round(values))
        if np.any(bad):
            row = int(np.argmax(bad))
            raise ValueError(
                f"{where}: column 'rss_dbm' must hold integers, got {rss.iloc[row]!r} at data row {row + 1}"
            )
        rss_values = values.astype(np.int64)
    lo, hi = RSS_RANGE_DBM
    bad = (rss_values < lo) | (rss_values > hi)
    if np.any(bad):
        row = int(np.argmax(bad))
        raise ValueError(
            f"{where}: column 'rss_dbm' value {rss_values[row]} at data row {row + 1} is outside [{lo}, {hi}] dBm"
        )
    out["rss_dbm"] = rss_values
    for column in TEXT_COLUMNS:
        values = df[column].to_numpy(dtype=object)
        codes, uniques = pd.factorize(values, use_na_sentinel=False)
        for code, value in enumerate(uniques):  # check each distinct name once
            if not isinstance(value, str) or not value or any(c in value for c in ',"\n\r') or value != value.strip():
                row = int(np.argmax(codes == code))
                raise ValueError(
                    f"{where}: column {column!r} has an empty or invalid name {value!r} at data row {row + 1}"
                )
        out[column] = values
    for column, allowed, what in (("anchor", anchors, "anchors"), ("target", targets, "targets")):
        stray = sorted(set(out[column]) - set(allowed))
        if stray:
            raise ValueError(
                f"{where}: column {column!r} has {what[:-1]}(s) {stray} not in the sidecar's {what} {list(allowed)}"
            )
    frame = pd.DataFrame({c: out[c] for c in COLUMNS})
    return frame


def block_order(frame: pd.DataFrame) -> np.ndarray:
    """Block index per row: (user, session) pairs numbered in order of first appearance."""
    keys = frame["user"].astype(str) + "\x1f" + frame["session"].astype(str)
    codes, _ = pd.factorize(keys, sort=False)
    return codes


def sort_rows(frame: pd.DataFrame, anchors, targets) -> pd.DataFrame:
    """Rows in file order: (user, session) blocks in order of appearance, then time, target, anchor."""
    block = block_order(frame)
    t_rank = frame["target"].map({t: i for i, t in enumerate(targets)}).to_numpy()
    a_rank = frame["anchor"].map({a: i for i, a in enumerate(anchors)}).to_numpy()
    order = np.lexsort((a_rank, t_rank, frame["time_s"].to_numpy(), block))
    return frame.iloc[order].reset_index(drop=True)


def check_rows(frame: pd.DataFrame, anchors, targets, where: str) -> None:
    """Order, uniqueness and per-packet consistency of an already sorted-or-not table."""
    block = block_order(frame)
    if np.any(np.diff(block) < 0):
        row = int(np.argmax(np.diff(block) < 0)) + 1
        raise ValueError(
            f"{where}: column 'session': rows of each (user, session) must be contiguous; data row {row + 1} "
            f"returns to an earlier block"
        )
    t_rank = frame["target"].map({t: i for i, t in enumerate(targets)}).to_numpy()
    a_rank = frame["anchor"].map({a: i for i, a in enumerate(anchors)}).to_numpy()
    time = frame["time_s"].to_numpy()
    key = np.stack([block, time, t_rank, a_rank], axis=1)
    same_block = block[1:] == block[:-1]
    step = key[1:] - key[:-1]
    # Lexicographic comparison of consecutive rows within a block.
    first_nonzero = np.argmax(step[:, 1:] != 0, axis=1)
    sign = np.sign(step[np.arange(len(step)), 1 + first_nonzero])
    all_zero = ~np.any(step[:, 1:] != 0, axis=1)
    bad_order = same_block & ~all_zero & (sign < 0)
    if np.any(bad_order):
        row = int(np.argmax(bad_order)) + 1
        raise ValueError(
            f"{where}: column 'time_s': rows must be ordered by time, target, anchor within each (user, session); "
            f"data row {row + 1} is out of order"
        )
    dup = same_block & all_zero
    if np.any(dup):
        row = int(np.argmax(dup)) + 1
        raise ValueError(
            f"{where}: column 'anchor': duplicate report of one packet by one anchor at data row {row + 1}"
        )
    packet = same_block & (step[:, 1] == 0) & (step[:, 2] == 0)
    for column in ("label", "x_m", "y_m", "z_m"):
        values = frame[column].to_numpy()
        differs = packet & (values[1:] != values[:-1])
        if np.any(differs):
            row = int(np.argmax(differs)) + 1
            raise ValueError(
                f"{where}: column {column!r} differs between rows of the same packet at data row {row + 1}"
            )
