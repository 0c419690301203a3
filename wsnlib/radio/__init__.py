"""Radio fingerprinting (paper 002's radio wing): radio map, kNN with Shepard weights,
probabilistic kNN (p-kNN), and the grid engine the exhaustive parameter search runs on.

Modules
-------
* :mod:`wsnlib.radio.estimators`: :class:`KNNFingerprint`, :class:`ProbabilisticKNN`
  (scikit-learn estimators) and :func:`fit_predict_by_group` (one radio map per user and
  target);
* :mod:`wsnlib.radio.grid`: :func:`anchor_subsets`, :func:`knn_from_terms`,
  :func:`knn_grid_from_terms`, :func:`pknn_from_loglik`, :func:`pknn_grid_from_loglik` —
  estimates for many anchor subsets × ``k`` × Shepard exponents from one fit
  (:mod:`wsnlib.optimize` is built on them);
* :mod:`wsnlib.radio._checks`: the argument checks and constants both share.

The RSS vectors these estimators take are built by :func:`wsnlib.io.vectors.window_readings`
(through :func:`wsnlib.io.rss.rss_vectors` for the simulated/CSV recordings and
:func:`wsnlib.io.pabr.pabr_vectors` for PABR), one type for both,
:class:`wsnlib.io.vectors.RssVectors`.

Paper 002 (M. Giuberti, M. Martalò, G. Ferrari, "A hybrid radio/accelerometric approach to
arm posture recognition"), Section 3.1, eqs. (1)–(4), and the Parzen-window / Gaussian
mixture PMFs its Section 5 proposes as extensions.

Conventions
-----------
* ``X`` (training or online RSS vectors): shape ``(n, A)`` in dBm, one column per anchor
  (7 anchors in the paper, 12 receivers in PABR).  Every training reading (and ``floor_rss``)
  must lie in :data:`RSS_RANGE_DBM` = [−130, 20] dBm, the span of any radio's RSS report: a
  value outside it is a glitch or a unit error and raises ``ValueError`` naming ``X`` and the
  index (so one −1e9 glitch cannot ask for a giant PMF grid); so does training data with no
  reading at all (every entry NaN) or whose readings are all ≥ 0 (linear power such as mW,
  not dBm: convert with ``10·log10(P / 1 mW)``).  Online vectors are not range-checked: the
  p-kNN clips them to ``grid_``, the kNN measures their distance as it is.
* Online vectors are processed in chunks of at most about 4 million (vector, fingerprint,
  anchor) values (32 MB per intermediate array), so ``predict`` of 100,000 vectors needs a
  few hundred MB at most, with results identical to an unchunked computation.
* ``y`` (positions): shape ``(n, D)``, normally ``D = 3`` metres (any coordinates work; the
  estimate is a weighted mean of them).  Training vectors whose rows of ``y`` are equal form
  one *fingerprint position*; positions are numbered in order of first appearance
  (``positions_[l]``), so the result does not depend on sorting.
* **Missing readings in training.**  ``NaN`` in ``X`` passed to ``fit`` means "this anchor
  did not report in this vector".  It is left out of that anchor's mean (radio map) and of
  its PMF; the other anchors of the same vector still count.  ``n_readings_[l, a]`` says how
  many readings each (position, anchor) cell got.  A cell with no reading at all gets the
  mean ``floor_rss`` (default −100 dBm, a "not heard" level) and, in
  :class:`ProbabilisticKNN`, a PMF that is a point mass at ``round(floor_rss)`` (before the
  floor probability is applied).  So an anchor that never hears a position looks, to both
  estimators, like an anchor that reads ``floor_rss`` there.
* **Missing online readings.**  By default (``online_missing="raise"``) online vectors must
  be complete: ``NaN`` in ``predict`` (and the other online methods) raises ``ValueError``.
  Fill missing readings first — with the anchor's last reading
  (:func:`wsnlib.io.pabr.pabr_vectors` / :func:`wsnlib.io.rss.rss_vectors` with
  ``fill="last"``), or with the "not heard" level (``fill=-100.0``), which treats an anchor
  that missed a window as a very weak one.  With ``online_missing="skip"`` a missing
  reading is left out of that vector instead: its distance term (kNN) or log-PMF term
  (p-kNN) is 0 at every fingerprint, so the vector is compared on the anchors it heard
  (exactly as with ``anchors`` set to them); a vector that heard none of the selected
  anchors raises ``ValueError``.
* ``anchors`` (both estimators): ``None`` (all), integer column indices, or a boolean mask of
  length ``A``.  It selects the anchors used for the distances / likelihoods; ``X`` always
  keeps all ``A`` columns, and the learned radio map and PMFs cover all anchors, so the
  per-anchor methods (:meth:`KNNFingerprint.anchor_terms`,
  :meth:`ProbabilisticKNN.anchor_log_likelihoods`) return every anchor and the module
  functions :func:`knn_from_terms` / :func:`pknn_from_loglik` evaluate many anchor subsets
  from one fit (exhaustive subset searches: see :func:`anchor_subsets`), and
  :func:`knn_grid_from_terms` / :func:`pknn_grid_from_loglik` every ``k`` (and Shepard
  exponent) of a grid at once, from one sort of the neighbours (:mod:`wsnlib.optimize`).
* Ties (equal distances or posteriors) are broken in favour of the lower fingerprint index.

Deterministic kNN, eqs. (1)–(2)
-------------------------------
Distance (Euclidean or Manhattan, over the selected anchors) from the online vector to every
radio-map row; the ``k`` nearest fingerprints; Shepard weights
``w_i = 1 / (d_i**p + 0.0001)``; estimate ``Σ w_i s_i / Σ w_j``.  With ``k = 1`` the nearest
fingerprint's position is returned exactly (``p`` irrelevant).  Should every ``d_i**p``
overflow to ``inf`` (absurd ``p``), the weights' limit, the nearest position, is returned.

Probabilistic kNN, eqs. (3)–(4)
-------------------------------
Per position ``l`` and anchor ``a``, a PMF over integer dBm values (1-dBm bins): readings are
rounded half up (``floor(r + 0.5)``), so bin ``g`` holds ``[g − 0.5, g + 0.5)``.  The grid
``grid_`` spans every training reading and ``floor_rss``, widened by ``grid_margin_db`` on
each side; online readings outside it are clipped to its edge bins.  Likelihood of an online
vector = product over the selected anchors of the PMF values of its readings (anchors taken
as independent given the position); uniform prior ``1/L``; posterior by Bayes (eq. (4)); the
``k`` positions of largest posterior, weighted by their posteriors (eq. (3)).  Everything is
computed in log space: sums of log-PMFs, normalised with log-sum-exp, so 7 or 12 anchors (or
any number) never underflow.

PMF estimators (``pmf=``):

* ``"histogram"`` (the paper): the normalised histogram of the rounded training readings.
* ``"parzen"``: Gaussian kernels of standard deviation ``h`` (dB) centred on the rounded
  readings; the PMF of bin ``g`` is the kernel mass in ``[g − 0.5, g + 0.5)``.  ``h`` is
  ``bandwidth_db`` if given, else Silverman's rule per (position, anchor),
  ``h = 0.9 · min(σ, IQR/1.34) · m**(-1/5)`` (``σ`` alone when the IQR is 0), never below
  ``min_bandwidth_db`` (0.5 dB: a zero-variance cell, which the paper observed, gets a kernel
  half a bin wide rather than a spike).  ``bandwidth_`` holds the values used.
* ``"gmm"``: a 1-D :class:`sklearn.mixture.GaussianMixture` per (position, anchor) with
  ``min(n_components, number of distinct readings)`` components, fitted to the unrounded
  readings with ``reg_covar = min_bandwidth_db**2`` (so no component is narrower than about
  ``min_bandwidth_db``), seeded from ``random_state``; the PMF of bin ``g`` is the mixture
  mass in ``[g − 0.5, g + 0.5)``.  A cell with one distinct value gets one Gaussian of
  standard deviation ``min_bandwidth_db`` there.  This loops over the ``L·A`` cells, each
  fit on one thread (``threadpoolctl``: on two busy cores, threaded k-means starts made PABR's
  81 × 12 cells of 300 two-packet means take 72 s instead of 6 s).

**Floor probability** (all three): every bin of every PMF is raised to at least
``floor_probability`` (ε, default 1e-4) and the PMF is then renormalised over the grid, so
no log 0 ever occurs: a reading never seen at a position costs about ``log ε`` instead of
ruling the position out.  With ``k = 1`` the MAP fingerprint position is returned.
"""

from wsnlib.radio import estimators, grid
from wsnlib.radio._checks import METRICS, PMF_METHODS, RSS_RANGE_DBM
from wsnlib.radio.estimators import KNNFingerprint, ProbabilisticKNN, fit_predict_by_group
from wsnlib.radio.grid import (
    SHEPARD_EPS,
    anchor_subsets,
    knn_from_terms,
    knn_grid_from_terms,
    pknn_from_loglik,
    pknn_grid_from_loglik,
)

__all__ = ["anchor_subsets", "estimators", "fit_predict_by_group", "grid", "KNNFingerprint", "knn_from_terms",
           "knn_grid_from_terms", "METRICS", "PMF_METHODS", "pknn_from_loglik", "pknn_grid_from_loglik",
           "ProbabilisticKNN", "RSS_RANGE_DBM", "SHEPARD_EPS"]
