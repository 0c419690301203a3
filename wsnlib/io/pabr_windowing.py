"""RSS vectors from the PABR packet tables (:func:`pabr_vectors`), with the one windowing
function of :mod:`wsnlib.io.vectors`; part of :mod:`wsnlib.io.pabr`, whose docstring
(section "Online vectors") documents the windows, the missing readings and the positions.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnlib.io.pabr_loaders import RSSI_MIN_DBM
from wsnlib.io.vectors import RssVectors, window_readings

#: The PABR path's vector type is the one RSS vector type (an alias, kept for old scripts;
#: its old field names ``positions``, ``times``, ``receivers``, ``counts``, ``groups``,
#: ``windows`` remain as read-only properties).
PabrVectors = RssVectors

#: Names that :func:`pabr_vectors` gives the fields the dataset has no column for.
PABR_USER = "PABR"
PABR_TARGET = "beacon"


def pabr_vectors(
    table: pd.DataFrame,
    *,
    window_s: float | None = None,
    window_packets: int | None = None,
    window: str | None = None,
    fill: str | float | None = None,
    floor_dbm: float = RSSI_MIN_DBM,
    min_receivers: int = 1,
    group: str | None = None,
) -> RssVectors:
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
        Ordered by group, then window.  ``label`` (old name ``groups``) is the point number or
        track name, ``session`` the same as text, ``user`` :data:`PABR_USER`, ``target``
        :data:`PABR_TARGET`.  A point's vectors all have its exact position.
    """
    if sum(arg is not None for arg in (window_s, window_packets, window)) != 1:
        raise ValueError(
            "give exactly one of window_s (seconds), window_packets (packets per receiver) and window='point'"
        )
    if group is None:
        group = "point" if "point" in table.columns else "track"
    if window is not None and (window != "point" or group != "point"):
        raise ValueError(f"window must be 'point' (one vector per fingerprint point, group 'point'), got {window!r}"
                         f" with group {group!r}")
    needed = [group, "timestamp", "receiver", "rssi", "x", "y", "z"]
    missing = [c for c in needed if c not in table.columns]
    if missing:
        raise ValueError(f"table lacks the column(s) {missing} (expected a load_pabr_* table)")
    if isinstance(min_receivers, bool) or not isinstance(min_receivers, int | np.integer) or min_receivers < 1:
        raise ValueError(f"min_receivers must be a positive integer, got {min_receivers!r}")
    receiver = table["receiver"]
    names = (
        list(receiver.cat.categories) if isinstance(receiver.dtype, pd.CategoricalDtype) else sorted(receiver.unique())
    )
    df = table[needed].copy()
    df["receiver"] = pd.Categorical(df["receiver"], categories=names)
    df = df.sort_values([group, "receiver", "timestamp"], kind="stable")
    label = df[group].to_numpy(dtype=object)
    readings = pd.DataFrame({
        "user": PABR_USER,
        "session": label.astype(str),
        "target": PABR_TARGET,
        "label": label,
        "anchor": df["receiver"].astype(object).to_numpy(),
        "rss_dbm": df["rssi"].to_numpy(dtype=float),
        "time_s": df["timestamp"].to_numpy(dtype=float),
        "x_m": df["x"].to_numpy(dtype=float),
        "y_m": df["y"].to_numpy(dtype=float),
        "z_m": df["z"].to_numpy(dtype=float),
    })
    return window_readings(readings, tuple(names), window_packets=window_packets, window_s=window_s, window=window,
                           complete_windows=True, fill=fill, floor_dbm=floor_dbm, min_anchors=min_receivers)
