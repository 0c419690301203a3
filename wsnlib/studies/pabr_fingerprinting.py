"""Paper 002's fingerprinting estimators on real BLE data (PABR): the checks of notebook 06.

The estimators are :mod:`wsnlib.radio`'s (kNN, eqs. (1)–(2); p-kNN, eqs. (3)–(4)); the data
:mod:`wsnlib.io.pabr`'s.  Every function returns one row per online vector, estimator and
condition, with the vector's *unit* (its reference point or track), so that tables are means
or medians over vectors and comparisons are paired over units
(:func:`compare_on_units`).

* :func:`score_models`: position errors (m) of fitted models on one set of vectors;
* :func:`online_gap_errors`: a moving beacon cut into time windows, where a receiver may hear
  no packet in a window: the missing reading filled with the "not heard" level, filled with
  the receiver's last reading, or left out (``online_missing="skip"``);
* :func:`pmf_source_errors`: p-kNN with PMFs from single packets (the paper's) or from means
  of ``n`` packets, against online vectors averaging 1, 3, … packets, on a same-day test
  (:func:`wsnlib.io.pabr.pabr_time_split`) and on the test set of another year.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Mapping

import numpy as np
import pandas as pd
from sklearn.base import clone

from wsnlib import metrics, stats
from wsnlib._validation import check_nonnegative, check_rng
from wsnlib.io.pabr import RSSI_MIN_DBM, pabr_vectors
from wsnlib.io.vectors import RssVectors

__all__ = ["ONLINE_TREATMENTS", "PairedComparison", "compare_on_units", "online_gap_errors", "pmf_source_errors",
           "score_models"]

#: How :func:`online_gap_errors` completes an online vector with a missing reading.
ONLINE_TREATMENTS = ("not heard", "last reading", "left out")


def score_models(models: Mapping, vectors: RssVectors, **columns) -> pd.DataFrame:
    """Position error (m) of every fitted model on every vector.

    Parameters
    ----------
    models : mapping name → fitted KNNFingerprint or ProbabilisticKNN
    vectors : RssVectors
        Complete vectors (or with NaN for models with ``online_missing="skip"``).
    **columns
        Constant columns to add (e.g. ``test="set 2"``, ``window=10``).

    Returns
    -------
    pandas.DataFrame
        One row per (model, vector), models in the order given: the ``columns``,
        ``estimator``, ``unit`` (the vector's label as text: point or track) and ``error_m``.
    """
    frames = [pd.DataFrame({**columns, "estimator": name, "unit": np.asarray(vectors.label).astype(str),
                            "error_m": metrics.position_error(model.predict(vectors.rss), vectors.position)})
              for name, model in models.items()]
    return pd.concat(frames, ignore_index=True)


def online_gap_errors(models: Mapping, tracks: pd.DataFrame, windows_s, *,
                      floor_dbm: float = RSSI_MIN_DBM) -> pd.DataFrame:
    """Errors on a moving beacon's time windows, with each way of completing a missing reading.

    For every window length the tracks are cut into time windows (:func:`pabr_vectors` with
    ``window_s``); a receiver with no packet in a window has a missing reading, which
    :data:`ONLINE_TREATMENTS` complete as

    * ``"not heard"``: ``floor_dbm`` (what a receiver reads when the beacon is out of range);
    * ``"last reading"``: the receiver's previous value on the track (``fill="last"``,
      causal; ``floor_dbm`` before its first packet);
    * ``"left out"``: not completed: a copy of the model with ``online_missing="skip"``
      compares the vector on the receivers it heard.

    Parameters
    ----------
    models : mapping name → fitted estimator
    tracks : DataFrame
        From :func:`wsnlib.io.pabr.load_pabr_tracks`.
    windows_s : sequence of float
        Window lengths (s).
    floor_dbm : float
        The "not heard" level (dBm).

    Returns
    -------
    pandas.DataFrame
        :func:`score_models`' columns with ``window_s``, ``treatment`` and ``incomplete``
        (whether the vector had a missing reading).  A complete vector gets the same error
        under every treatment.
    """
    frames = []
    for window in windows_s:
        raw = pabr_vectors(tracks, window_s=window)
        last = pabr_vectors(tracks, window_s=window, fill="last", floor_dbm=floor_dbm)
        incomplete = np.isnan(raw.rss).any(axis=1)
        filled = {"not heard": (models, np.where(np.isnan(raw.rss), floor_dbm, raw.rss)),
                  "last reading": (models, last.rss),
                  "left out": ({name: copy.copy(model).set_params(online_missing="skip")
                                for name, model in models.items()}, raw.rss)}
        for treatment in ONLINE_TREATMENTS:
            chosen, rss = filled[treatment]
            frames.append(score_models(chosen, dataclasses.replace(raw, rss=rss), window_s=float(window),
                                       treatment=treatment)
                          .assign(incomplete=np.tile(incomplete, len(chosen))))
    return pd.concat(frames, ignore_index=True)


def pmf_source_errors(estimators: Mapping, tests: Mapping, *, pmf_packets, windows, fill="last",
                      floor_dbm: float = RSSI_MIN_DBM) -> pd.DataFrame:
    """Errors with radio maps built from single packets or from means of packets.

    Paper 002 builds its PMFs from single packets; averaging ``n`` packets per map vector
    narrows every PMF (the spread of a mean), which suits online vectors that average as many
    packets and no others.  For every test, every ``pmf_packets`` value and every estimator, a
    clone is fitted on the test's map cut into blocks of that many packets per receiver
    (missing readings left out) and scored on the test points cut into blocks of each of
    ``windows`` packets (completed with ``fill``).

    Parameters
    ----------
    estimators : mapping name → unfitted KNNFingerprint or ProbabilisticKNN
    tests : mapping name → (map table, test table)
        :func:`wsnlib.io.pabr.load_pabr_fingerprints` tables (or parts of them,
        :func:`wsnlib.io.pabr.pabr_time_split`).
    pmf_packets : sequence of int
        Packets per receiver averaged into each map vector.
    windows : sequence of int
        Packets per receiver averaged into each online vector.
    fill, floor_dbm
        How online vectors are completed (:func:`pabr_vectors`).

    Returns
    -------
    pandas.DataFrame
        :func:`score_models`' columns with ``test``, ``pmf_packets`` and ``window``.
    """
    frames = []
    for test, (map_table, test_table) in tests.items():
        online = {window: pabr_vectors(test_table, window_packets=window, fill=fill, floor_dbm=floor_dbm)
                  for window in windows}
        for packets in pmf_packets:
            radio_map = pabr_vectors(map_table, window_packets=packets)
            models = {name: clone(est).fit(radio_map.rss, radio_map.position) for name, est in estimators.items()}
            frames += [score_models(models, vectors, test=test, pmf_packets=int(packets), window=int(window))
                       for window, vectors in online.items()]
    return pd.concat(frames, ignore_index=True)


@dataclasses.dataclass(frozen=True)
class PairedComparison:
    """Mean per-unit error of ``a`` minus that of ``b`` (m), with its bootstrap interval over units.

    ``verdict``: ``"lower"`` (the interval lies below ``−resolution_m``: ``a`` beats ``b``),
    ``"higher"`` (above ``+resolution_m``) or ``"tie"``.  The resolution keeps two estimators
    that both return the reference positions (errors of 1e-11 m, rounding) from being ranked.
    """

    a: float
    b: float
    difference: float
    low: float
    high: float
    n_units: int
    resolution_m: float

    @property
    def verdict(self) -> str:
        return "lower" if self.high < -self.resolution_m else "higher" if self.low > self.resolution_m else "tie"


def compare_on_units(errors: pd.DataFrame, a, b, *, by: str = "estimator", rng: np.random.Generator,
                     n_boot: int = 2000, level: float = 0.95, resolution_m: float = 1e-3) -> PairedComparison:
    """Paired comparison of two rows' errors over the units both were scored on.

    Parameters
    ----------
    errors : DataFrame
        Rows of one condition (columns ``unit``, ``error_m`` and ``by``).
    a, b
        Values of ``by`` (e.g. two estimator names).
    by : str
        The column that tells the two apart.
    rng, n_boot, level
        As in :func:`wsnlib.stats.paired_difference_ci` (percentile intervals).
    resolution_m : float
        Differences within ± this (m; default 1 mm, far below the spacing of PABR's points) are ties.

    Returns
    -------
    PairedComparison
        Each unit's mean error first, then the mean over units and the paired interval.
    """
    rng = check_rng(rng)
    per_unit = errors.pivot_table(index="unit", columns=by, values="error_m", aggfunc="mean", observed=True)
    missing = [name for name in (a, b) if name not in per_unit.columns]
    if missing:
        raise ValueError(f"no rows with {by} = {missing}")
    pair = per_unit[[a, b]].dropna()
    if len(pair) < 2:
        raise ValueError(f"{a!r} and {b!r} share fewer than 2 units")
    interval = stats.paired_difference_ci(pair[a].to_numpy(), pair[b].to_numpy(), rng=rng, n_boot=n_boot,
                                          level=level, method="percentile")
    return PairedComparison(a=float(pair[a].mean()), b=float(pair[b].mean()), difference=float(interval.estimate),
                            low=float(interval.low), high=float(interval.high), n_units=len(pair),
                            resolution_m=check_nonnegative(resolution_m, "resolution_m"))
