"""RSS vectors: the one vector type of radio fingerprinting, and the one function that cuts
readings into windows.

Both data paths build their vectors here: the simulated / CSV RSS recordings
(:func:`wsnlib.io.rss.rss_vectors`) and the PABR BLE dataset
(:func:`wsnlib.io.pabr.pabr_vectors`) turn their tables into a *readings* table and call
:func:`window_readings`, which returns :class:`RssVectors`.

Readings, points and windows
----------------------------
A *reading* is one receiver's (anchor's) report of one packet of a transmitter (target).
The *point* of a reading is what the transmitter was doing while it was sent: a maximal run
of consecutive readings with equal (``user``, ``session``, ``target``, ``label``) — a posture
held (simulated; the same posture held again later is another point), a reference point of a
fingerprint set or a walked track (PABR).  The point is built in one place
(:func:`_point_codes`) and a window never mixes two points.  Within a point, windows are

* ``window_packets=n``: packets ``j·n … j·n + n − 1`` of the point (in time order) form window
  ``j``.  Packets are identified by the readings' ``packet`` column where the data has one
  (simulated: one transmission, reported by several anchors); without it (PABR's receivers log
  independently) each receiver's own ``j``-th block of ``n`` readings forms window ``j``.  With
  ``complete_windows=True`` an incomplete last block is dropped, so each value averages
  exactly ``n`` packets;
* ``window_s=w``: ``[t0 + j·w, t0 + (j+1)·w)``, ``t0`` the point's first reading;
* ``window="point"``: the whole point (one vector per point: the classic radio-map
  fingerprint).

Missing readings and ``fill``
-----------------------------
A vector holds, per anchor, the mean RSS (dBm, the mean of the dBm values, as paper 002
averages fingerprints) of the readings in its window, and **NaN where the anchor had none**:
a missing reading, not a weak one.  The estimators of :mod:`wsnlib.radio` leave NaN out of a
training map (a training map is built without ``fill``: filling it with a "not heard" level
biases the cell's mean).  Online vectors must be complete; ``fill`` completes them:

* ``None`` (default): keep NaN;
* ``"last"``: carry each anchor's previous value forward within the stream (``user``,
  ``session``, ``target``), as a causal online system would, and ``floor_dbm`` before the
  anchor's first reading;
* ``"floor"``: ``floor_dbm`` wherever a reading is missing;
* a number: that value (dBm) wherever a reading is missing (``"floor"`` at that level).

``n_readings`` always counts the readings actually received (0 where a value was filled).
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, fields

import numpy as np
import pandas as pd

from wsnlib._validation import check_count, check_positive

#: Columns of a readings table (input of :func:`window_readings`); ``packet`` is optional.
READING_COLUMNS: tuple[str, ...] = ("user", "session", "target", "label", "anchor", "rss_dbm", "time_s",
                                    "x_m", "y_m", "z_m")

FILL_MODES = (None, "last", "floor")


@dataclass(frozen=True, eq=False)
class RssVectors:
    """RSS vectors (fingerprints): one row per window of readings of one transmitter.

    Built by :func:`window_readings` (through :func:`wsnlib.io.rss.rss_vectors` or
    :func:`wsnlib.io.pabr.pabr_vectors`).  ``n`` vectors, ``A`` anchors (receivers).

    Attributes
    ----------
    rss : numpy.ndarray (n, A)
        Mean RSS (dBm) per anchor in :attr:`anchors` order over the window's readings; NaN
        where the anchor had no reading (unless ``fill`` was given).
    n_readings : numpy.ndarray of int (n, A)
        Readings averaged into each entry (0: none received, the entry is NaN or filled).
    time_s : numpy.ndarray (n,)
        Time (s) of the window's last reading: when the vector becomes available online.
    first_time_s : numpy.ndarray (n,)
        Time (s) of the window's first reading; ``time_s − first_time_s`` is the time the
        vector spans (a moving transmitter moves during it).
    position : numpy.ndarray (n, 3)
        True transmitter position (m).  Exactly the point's position where the point has one
        (a held posture, a fingerprint reference point: every vector of it has the same
        position, so the estimators see one fingerprint per point); else (a moving target,
        a track) the mean over the window's packets.
    label : numpy.ndarray (n,) object
        The point's label: a posture or movement name (simulated), a reference point's number
        or a track's name (PABR).
    target, session, user : numpy.ndarray (n,) object
        Transmitter, session and user of the point (PABR: ``"beacon"``, the point's label,
        ``"PABR"``).
    window : numpy.ndarray of int (n,)
        Index ``j`` of the window within its point (0 for ``window="point"``).
    n_packets : numpy.ndarray of int (n,)
        Packets in the window (where packets are not identified, PABR: the most readings of
        one anchor).
    anchors : tuple of str
        Column order of ``rss`` and ``n_readings``.
    """

    rss: np.ndarray
    n_readings: np.ndarray
    time_s: np.ndarray
    first_time_s: np.ndarray
    position: np.ndarray
    label: np.ndarray
    target: np.ndarray
    session: np.ndarray
    user: np.ndarray
    window: np.ndarray
    n_packets: np.ndarray
    anchors: tuple[str, ...]

    def __len__(self) -> int:
        return self.time_s.size

    @property
    def map_key(self) -> np.ndarray:
        """``"user/target"`` per vector: the radio map the vector belongs to (paper 002, Sec. 4.1,
        fits one per user and target node); the ``groups`` of
        :func:`wsnlib.radio.fit_predict_by_group`."""
        return np.char.add(np.asarray(self.user).astype(str), "/" + np.asarray(self.target).astype(str))

    def select(self, *, target=None, session=None, user=None, label=None) -> RssVectors:
        """The vectors matching every given value (a name or a collection of names)."""
        return select_rows(self, target=target, session=session, user=user, label=label)


def select_rows(record, **wanted):
    """``record`` (a dataclass of per-row arrays and an ``anchors`` tuple: :class:`RssVectors`,
    :class:`wsnlib.sim.campaign.DynamicData`) cut to the rows whose fields match every given value
    (a value or a collection of values; None matches all)."""
    keep = np.ones(len(record), dtype=bool)
    for name, value in wanted.items():
        if value is not None:
            keep &= np.isin(getattr(record, name), [value] if isinstance(value, str | numbers.Number) else list(value))
    return type(record)(**{f.name: getattr(record, f.name)[keep] for f in fields(record) if f.name != "anchors"},
                        anchors=record.anchors)


def _point_codes(readings: pd.DataFrame) -> np.ndarray:
    """Point index per reading: runs of consecutive rows with equal (user, session, target,
    label), numbered in order of appearance.  The one place the point key is built."""
    codes = [pd.factorize(readings[column].to_numpy(dtype=object), sort=False)[0]
             for column in ("user", "session", "target", "label")]
    change = np.zeros(len(readings), dtype=bool)
    change[0] = True
    for code in codes:
        change[1:] |= code[1:] != code[:-1]
    return np.cumsum(change) - 1


def _check_window(window_packets, window_s, window) -> None:
    if sum(arg is not None for arg in (window_packets, window_s, window)) != 1:
        raise ValueError("give exactly one of window_packets (packets per window), window_s (seconds) and "
                         "window='point'")
    if window_packets is not None:
        check_count(window_packets, "window_packets")
    if window_s is not None:
        check_positive(window_s, "window_s")
    if window is not None and window != "point":
        raise ValueError(f"window must be 'point' (one vector per point), got {window!r}")


def _check_fill(fill, floor_dbm) -> float | None:
    """The constant of ``fill`` (None for ``fill=None``); ValueError naming the argument."""
    if fill is None:
        return None
    if isinstance(fill, str):
        if fill not in FILL_MODES:
            raise ValueError(f"fill must be None, 'last', 'floor' or a number (dBm), got {fill!r}")
        value = floor_dbm
        if value is None:
            raise ValueError(f"fill={fill!r} needs floor_dbm (the 'not heard' level, dBm)")
        name = "floor_dbm"
    elif isinstance(fill, bool) or not isinstance(fill, numbers.Real):
        raise ValueError(f"fill must be None, 'last', 'floor' or a number (dBm), got {fill!r}")
    else:
        value, name = fill, "fill"
    value = float(value)
    if not np.isfinite(value):
        raise ValueError(f"{name} must be a finite number (dBm), got {value!r}")
    return value


def window_readings(readings: pd.DataFrame, anchors, *, window_packets: int | None = None,
                    window_s: float | None = None, window: str | None = None, complete_windows: bool = False,
                    fill: str | float | None = None, floor_dbm: float | None = None,
                    min_anchors: int = 1) -> RssVectors:
    """RSS vectors from a readings table: the one windowing function (see the module docstring).

    Parameters
    ----------
    readings : pandas.DataFrame
        One row per reading, columns :data:`READING_COLUMNS`: ``user``, ``session``,
        ``target``, ``label`` (define the point), ``anchor`` (one of ``anchors``),
        ``rss_dbm`` (dBm), ``time_s`` (s), ``x_m``, ``y_m``, ``z_m`` (true position, m); and
        optionally ``packet`` (packet id: rows with equal ids in a point are one packet and
        share its time stamp).
        The rows of a point must be consecutive (e.g. ordered by stream, then time).
    anchors : sequence of str
        Vector columns, in order.
    window_packets, window_s, window
        Exactly one: packets per window, window length (s), or ``"point"``.
    complete_windows : bool
        With ``window_packets``, drop an incomplete last block (default keep it shorter).
    fill : None, "last", "floor" or float
        What replaces a missing reading (module docstring); default keep NaN.
    floor_dbm : float, optional
        The "not heard" level (dBm) of ``"last"`` and ``"floor"``.
    min_anchors : int
        Drop vectors with readings from fewer anchors than this (default 1: keep all).

    Returns
    -------
    RssVectors
        Ordered by point (in order of appearance), then window.
    """
    _check_window(window_packets, window_s, window)
    fill_value = _check_fill(fill, floor_dbm)
    check_count(min_anchors, "min_anchors")
    anchors = tuple(anchors)
    missing = [c for c in READING_COLUMNS if c not in readings.columns]
    if missing:
        raise ValueError(f"readings lacks the column(s) {missing}; expected {list(READING_COLUMNS)}")
    n_anchors = len(anchors)
    if len(set(anchors)) != len(anchors):
        raise ValueError(f"anchors holds duplicate names: {list(anchors)}")
    # One hash lookup per reading (-1: not an anchor); Series.map is far slower on pandas' string dtype.
    anchor_index = pd.Index(list(anchors), dtype=object).get_indexer(readings["anchor"].to_numpy(dtype=object))
    if len(readings) and np.any(anchor_index < 0):
        stray = sorted(set(readings["anchor"].astype(str)) - set(anchors))
        raise ValueError(f"readings has anchor(s) {stray} not in anchors {list(anchors)}")
    if len(readings) == 0:
        return _empty(anchors)
    anchor_index = anchor_index.astype(np.intp)
    for column in ("rss_dbm", "time_s", "x_m", "y_m", "z_m"):
        values = pd.to_numeric(readings[column], errors="coerce").to_numpy(dtype=float)
        if not np.all(np.isfinite(values)):
            row = int(np.argmax(~np.isfinite(values)))
            raise ValueError(f"readings column {column!r} must hold finite numbers, got "
                             f"{readings[column].iloc[row]!r} at row {row}")

    point = _point_codes(readings)
    time = readings["time_s"].to_numpy(dtype=float)
    has_packets = "packet" in readings.columns
    # Within a point: time order (packets), or per anchor in time order (anchors' own blocks);
    # stable, so readings of equal time keep their order.
    order = np.lexsort((time, point)) if has_packets else np.lexsort((time, anchor_index, point))
    point, time, anchor_index = point[order], time[order], anchor_index[order]
    rows = readings.iloc[order]
    first_of_point = np.flatnonzero(np.r_[True, point[1:] != point[:-1]])
    start = first_of_point[point]  # first row of each row's point
    keep = np.ones(len(rows), dtype=bool)
    if window is not None:
        win = np.zeros(len(rows), dtype=np.int64)
    elif window_s is not None:
        first_time = np.minimum.reduceat(time, first_of_point)[point]  # points are numbered 0, 1, … in order
        win = np.floor((time - first_time) / float(window_s)).astype(np.int64)
    elif has_packets:
        packet = rows["packet"].to_numpy()
        new_packet = np.r_[True, (point[1:] != point[:-1]) | (packet[1:] != packet[:-1])]
        sequence = np.cumsum(new_packet) - 1
        rank = sequence - sequence[start]
        win = rank // window_packets
        if complete_windows:
            size = np.bincount(point, weights=new_packet).astype(np.int64)  # packets per point
            keep = rank < (size[point] // window_packets) * window_packets
    else:  # no packet ids: each anchor's own readings, in time order, in blocks
        cell = pd.Series(point * n_anchors + anchor_index)
        rank = cell.groupby(cell).cumcount().to_numpy()
        win = rank // window_packets
        if complete_windows:
            size = cell.map(cell.value_counts()).to_numpy()
            keep = rank < (size // window_packets) * window_packets
    if not keep.all():
        point, time, anchor_index, win, rows = point[keep], time[keep], anchor_index[keep], win[keep], rows[keep]
        if len(rows) == 0:
            return _empty(anchors)

    # Mean position per (point, window) over its packets (each once: its readings share its
    # position) or, without packet ids, over its readings; grouped in the order above (sums in
    # the same order whatever the windowing).
    xyz = rows[["x_m", "y_m", "z_m"]].to_numpy(dtype=float)
    if has_packets:
        packet = rows["packet"].to_numpy()
        once = np.flatnonzero(np.r_[True, (point[1:] != point[:-1]) | (packet[1:] != packet[:-1])])
    else:
        once = np.arange(len(rows))
    by_window = pd.DataFrame(xyz[once]).groupby([point[once], win[once]])
    position = by_window.mean().to_numpy(copy=True)  # sorted by (point, window): the vectors' order
    n_packets = by_window.size().to_numpy()
    # A point with one position (a held posture, a reference point) keeps it exactly: the float
    # mean of equal values need not equal them (0.19 vs 0.18999999999999997), and the estimators
    # tell fingerprints apart by exact equality of positions.
    by_point = pd.DataFrame(xyz).groupby(point)
    low, high = by_point.min().to_numpy(), by_point.max().to_numpy()

    by_vector = np.lexsort((win, point))  # stable: the order above within each window
    point, time, anchor_index, win = point[by_vector], time[by_vector], anchor_index[by_vector], win[by_vector]
    rows = rows.iloc[by_vector]
    new_vector = np.r_[True, (point[1:] != point[:-1]) | (win[1:] != win[:-1])]
    vector = np.cumsum(new_vector) - 1
    n_vectors = int(vector[-1]) + 1
    first = np.flatnonzero(new_vector)

    cell = vector * n_anchors + anchor_index
    counts = np.bincount(cell, minlength=n_vectors * n_anchors).reshape(n_vectors, n_anchors)
    sums = np.bincount(cell, weights=rows["rss_dbm"].to_numpy(dtype=float),
                       minlength=n_vectors * n_anchors).reshape(n_vectors, n_anchors)
    rss = np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)

    if not has_packets:
        n_packets = counts.max(axis=1)
    point_of_vector = np.unique(point, return_inverse=True)[1][first]  # 0, 1, … even if a point was dropped
    exact = (low[point_of_vector] == high[point_of_vector]).all(axis=1)
    position[exact] = low[point_of_vector[exact]]
    last_time = np.maximum.reduceat(time, first)
    first_time = np.minimum.reduceat(time, first)

    if fill == "last":
        stream = pd.DataFrame({c: rows[c].to_numpy(dtype=object)[first] for c in ("user", "session", "target")})
        stream_code = stream.groupby(list(stream.columns), sort=False).ngroup().to_numpy()
        rss = pd.DataFrame(rss).groupby(stream_code).ffill().to_numpy()
    if fill_value is not None:
        rss = np.where(np.isnan(rss), fill_value, rss)

    take = (counts > 0).sum(axis=1) >= min_anchors
    meta = {c: rows[c].to_numpy(dtype=object)[first][take] for c in ("user", "session", "target", "label")}
    return RssVectors(rss=rss[take], n_readings=counts[take], time_s=last_time[take],
                      first_time_s=first_time[take], position=position[take],
                      window=win[first][take], n_packets=n_packets[take], anchors=anchors, **meta)


def _empty(anchors: tuple[str, ...]) -> RssVectors:
    n_anchors = len(anchors)
    empty = np.empty((0,), dtype=object)
    return RssVectors(rss=np.empty((0, n_anchors)), n_readings=np.zeros((0, n_anchors), dtype=np.int64),
                      time_s=np.empty(0), first_time_s=np.empty(0), position=np.empty((0, 3)), label=empty,
                      target=empty, session=empty, user=empty, window=np.zeros(0, dtype=np.int64),
                      n_packets=np.zeros(0, dtype=np.int64), anchors=anchors)
