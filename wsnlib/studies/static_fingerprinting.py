"""Static fingerprinting at one kNN setting: position error per posture and target (paper 002, Sec. 4.1).

:func:`static_fingerprinting` fits one radio map per user and target, localises every online
vector of the static session with kNN (k, Shepard exponent p_s, a chosen anchor set) and
returns the position errors and their means; :func:`wsnlib.plotting.plot_static_fingerprinting`
draws them.  Fast enough to rerun whenever a knob of :func:`wsnlib.interactive.explore` moves.
:func:`own_posture` says which estimates are exactly the fingerprint of the vector's own posture
(static localisation as classification).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnlib import metrics
from wsnlib.radio import KNNFingerprint, fit_predict_by_group

__all__ = ["StaticFingerprinting", "own_posture", "static_fingerprinting"]


@dataclass(frozen=True)
class StaticFingerprinting:
    """What :func:`static_fingerprinting` returns.

    Attributes
    ----------
    error_cm : numpy.ndarray (n,)
        Position error (cm, paper 002 eq. (11)) of every online vector.
    posture, target : numpy.ndarray (n,)
        Posture label and target node of every online vector.
    mean_by_posture : pandas.DataFrame
        Mean error (cm): index ``posture``, one column per target.
    mean_by_target : pandas.Series
        Mean error (cm) over all online vectors of each target (index: target).
    anchors : tuple of int
        Column indices of the anchors used.
    """

    error_cm: np.ndarray
    posture: np.ndarray
    target: np.ndarray
    mean_by_posture: pd.DataFrame
    mean_by_target: pd.Series
    anchors: tuple


def static_fingerprinting(train, online, *, n_neighbors, power, anchors, metric="euclidean") -> StaticFingerprinting:
    """Position errors of kNN on the online static session, per posture and target.

    Fits :class:`wsnlib.radio.KNNFingerprint` (k = ``n_neighbors``, Shepard exponent ``power``,
    the chosen anchors) per user and target (:func:`wsnlib.radio.fit_predict_by_group`) on
    ``train`` and localises every vector of ``online``.

    Parameters
    ----------
    train, online : wsnlib.io.vectors.RssVectors
        Training vectors (NaN allowed) and complete online vectors, with ``user``,
        ``target``, ``label`` (posture) and ``position`` (m); the radio maps are keyed by
        :attr:`~wsnlib.io.vectors.RssVectors.map_key` (``"user/target"``).
    n_neighbors : int
        k (≤ the number of postures).
    power : float
        Shepard exponent p_s (paper 002, eq. (2)).
    anchors : sequence of str or int
        Anchor names (from ``train.anchors``) or column indices; at least one.
    metric : {"euclidean", "manhattan"}

    Returns
    -------
    StaticFingerprinting

    Raises
    ------
    ValueError
        ``anchors`` is empty or names an anchor not in ``train.anchors``.
    """
    anchors = list(anchors)
    if not anchors:
        raise ValueError("anchors must name at least one anchor")
    names = list(train.anchors)
    unknown = [a for a in anchors if not isinstance(a, int | np.integer) and a not in names]
    if unknown:
        raise ValueError(f"anchors names anchors not in train.anchors {names}: {unknown}")
    columns = [int(a) if isinstance(a, int | np.integer) else names.index(a) for a in anchors]
    estimator = KNNFingerprint(n_neighbors, metric=metric, power=power, anchors=columns)
    estimate = fit_predict_by_group(estimator, train.rss, train.position, train.map_key, online.rss, online.map_key)
    error_cm = 100 * metrics.position_error(estimate, online.position)
    posture, target = np.asarray(online.label), np.asarray(online.target)
    mean_by_posture = (pd.DataFrame({"posture": posture, "target": target, "PE": error_cm})
                       .groupby(["posture", "target"])["PE"].mean().unstack("target"))
    mean_by_target = pd.Series(error_cm).groupby(target).mean()
    return StaticFingerprinting(error_cm=error_cm, posture=posture, target=target, mean_by_posture=mean_by_posture,
                                mean_by_target=mean_by_target, anchors=tuple(columns))


def own_posture(train, online, estimate) -> np.ndarray:
    """Whether each estimate is exactly the fingerprint position of its online vector's own posture.

    Static localisation is a classification in disguise: NN (k = 1) and the MAP p-kNN return
    one fingerprint position, the right posture's or another's.

    Parameters
    ----------
    train, online : wsnlib.io.vectors.RssVectors
        As in :func:`static_fingerprinting` (``label`` is the posture).
    estimate : array_like (n, 3)
        Estimated positions (m) of ``online``'s vectors.

    Returns
    -------
    numpy.ndarray of bool (n,)

    Raises
    ------
    ValueError
        An online vector whose (user, target, posture) has no training vector.
    """
    estimate = np.asarray(estimate, dtype=float)
    if estimate.shape != online.position.shape:
        raise ValueError(f"estimate must have shape {online.position.shape} like online.position, got {estimate.shape}")
    fingerprint = {}
    for key, label, position in zip(train.map_key, train.label, train.position, strict=True):
        fingerprint.setdefault((key, label), position)
    wanted = set(zip(online.map_key, online.label, strict=True))
    missing = sorted(wanted - set(fingerprint), key=str)
    if missing:
        raise ValueError(f"online postures without training vectors: {missing[:5]}")
    own = np.array([fingerprint[key, label] for key, label in zip(online.map_key, online.label, strict=True)])
    return np.all(estimate == own, axis=1)
