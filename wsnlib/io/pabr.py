"""Loader of the PABR dataset (or the project's subset of it): real BLE RSS fingerprints and
tracks (a real-data check of :mod:`wsnlib.radio`).

Data credit
-----------
F. S. Daniş, A. T. Naskali, A. T. Cemgil, C. Ersoy, "An Indoor Localization Dataset and Data
Collection Framework with High Precision Position Annotation", *Pervasive and Mobile
Computing* 81, 2022 ("Position Annotated BLE RSSI Dataset for Indoor Localization",
github.com/philotuxo/Position-Annotated-BLE-RSSI-Dataset).  Released under CC0 1.0; cite the
article wherever results from it are shown.

Folder and download
-------------------
First match wins: the ``data_dir`` argument; else the environment variable
``WSNLIB_PABR_DIR``; else ``<ROOT>/data/raw/pabr/`` (ROOT is :data:`wsnlib.paths.ROOT`).
It holds the dataset's own layout: ``cnf/tetam.dev``, ``hst/set_1/``, ``hst/set_2/``,
``trk/*_all_sensors.mbd``.  What a loader needs and does not find there is downloaded with
pooch from the dataset's repository pinned to commit :data:`PABR_COMMIT`
(``https://raw.githubusercontent.com/philotuxo/Position-Annotated-BLE-RSSI-Dataset/<commit>/<path>``)
into that folder, each file kept only if its SHA-256 matches :data:`PABR_REGISTRY` (shipped as
``wsnlib/registry/pabr.tsv``; the whole dataset part the loaders read is about 266 MB in 1,523
files): the device file (with ``LICENSE.md``) when ``cnf/tetam.dev`` is missing; every file of a
fingerprint set when its folder holds no ``.mbd`` file; a track whose file is missing (all
tracks when ``trk/`` holds none).  Files already there are read as they are, unverified: the
project's shared copy is a documented subset (cut per point, see ``common_span_packets``), not
the registry's full files.  ``download=False`` turns a missing file into ``FileNotFoundError``
naming it and the variable; a failed download is an ``OSError``, a hash mismatch a
``ValueError`` (leaving no file behind).  Tests inject a ``downloader`` (no network).

What the loaders return
-----------------------
* :func:`load_pabr_receivers`: the 12 BLE receivers (our anchors) in the order of
  ``tetam.dev`` — columns ``receiver`` (alias, e.g. ``"sensor10"``), ``mac``, ``x``, ``y``,
  ``z`` (m); the beacon (our target) in ``attrs["beacon"]``.
* :func:`load_pabr_fingerprints` (``"set_1"``: 81 reference points, 2019; ``"set_2"``: 45
  other points, 2020): one row per received packet — ``point`` (int, points numbered in
  order of (x, y, z)), ``x``, ``y``, ``z`` (m, parsed from the file names
  ``<sensor>_<x>_<y>_<z>.mbd``), ``receiver`` (categorical, in receiver order),
  ``timestamp`` (Unix s), ``rssi`` (dBm).  Every receiver of ``tetam.dev`` must have at least
  one file in the set (else ``ValueError`` naming it: a silently missing receiver would turn
  12 anchors into 11).
* :func:`load_pabr_tracks`: one row per packet of the walked trajectories — ``track``
  (categorical, the file name less ``_all_sensors.mbd``), ``timestamp``, ``receiver``,
  ``rssi``, and ``x``, ``y``, ``z``: the AR ground-truth position (m) of the beacon when the
  packet was received (the 3×3 orientation matrix of each line is not kept).  A receiver
  heard in no track is reported by a ``UserWarning``.

Parsing is strict: a line with the wrong number of fields, a field that is not a number, or a
non-finite number (``nan``, ``inf``) raises ``ValueError`` naming the file and the line.
Invalid readings — RSSI above 0 dBm or below −100 dBm (:data:`RSSI_MIN_DBM`) — are dropped.
How many is in ``DataFrame.attrs`` (``n_packets_read``, ``n_dropped_invalid_rssi``) and
logged at INFO level.  The dataset has no missing-value code: a receiver that did not hear
a packet simply has no line.

Online vectors: :func:`pabr_vectors`
------------------------------------
Packets arrive one receiver at a time, so a vector of 12 RSS values must be assembled.
Within each point (fingerprints) or track, either

* ``window_s=w``: consecutive time windows ``[t0 + j·w, t0 + (j+1)·w)``, ``t0`` the group's
  first packet; or
* ``window_packets=n``: per receiver, its packets in time order cut into blocks of ``n``
  (block ``j`` = that receiver's packets ``j·n … j·n + n − 1``; the last incomplete block is
  dropped), so each value averages exactly ``n`` packets.  Use this to study how the error
  depends on the number of packets averaged; for a moving beacon prefer ``window_s``, since
  the receivers' ``j``-th blocks need not cover the same moment; or
* ``window="point"`` (fingerprints only): one vector per point, each receiver's mean over
  all its packets there — the classic radio-map fingerprint.

The windowing is :func:`wsnlib.io.vectors.window_readings`, the same function the simulated
path (:func:`wsnlib.io.rss.rss_vectors`) calls, and the result the one vector type,
:class:`wsnlib.io.vectors.RssVectors` (``PabrVectors`` is an alias; receivers are its
``anchors``).  Vector ``j`` holds, per receiver, the mean RSS (dBm) of its packets in
window/block ``j``, and ``NaN`` where that receiver had none: a missing reading, which
:mod:`wsnlib.radio` leaves out of training, so a training map is built without ``fill``.  Filling a training
map with a "not heard" level biases it (a receiver that skipped a window is not a very weak
one).  Online vectors must be complete: fill those with ``fill=`` (e.g. ``-100.0``, the
estimators' default ``floor_rss``).  The position of a vector is exact where its group has
one position (a fingerprint point: the position parsed from the file names, so every vector
of a point has the same position and the estimators see one fingerprint per point); else
(tracks) the mean ground-truth position of its packets.  Its time ``time_s`` is the timestamp
of its last packet (when the vector is available; the mean timestamp before issue 13).

The code is in three modules, re-exported here (this is the dataset's public path):
:mod:`wsnlib.io.pabr_download` (folder, registry, verified download),
:mod:`wsnlib.io.pabr_loaders` (parsing the files into tables) and
:mod:`wsnlib.io.pabr_windowing` (:func:`pabr_vectors`).  Tests that replace the registry
patch it where it is read, ``wsnlib.io.pabr_download.PABR_REGISTRY``.
"""

from wsnlib.io.pabr_download import (
    PABR_COMMIT,
    PABR_DIR_ENV_VAR,
    PABR_REGISTRY,
    PABR_URL,
    pabr_dir,
    pabr_file,
)
from wsnlib.io.pabr_loaders import (
    FINGERPRINT_SETS,
    RSSI_MAX_DBM,
    RSSI_MIN_DBM,
    SUBSET_SPAN_PACKETS,
    load_pabr_fingerprints,
    load_pabr_receivers,
    load_pabr_tracks,
    pabr_track_names,
)
from wsnlib.io.pabr_windowing import PABR_TARGET, PABR_USER, PabrVectors, pabr_vectors

__all__ = [
    "FINGERPRINT_SETS",
    "load_pabr_fingerprints",
    "load_pabr_receivers",
    "load_pabr_tracks",
    "PABR_COMMIT",
    "pabr_dir",
    "PABR_DIR_ENV_VAR",
    "pabr_file",
    "PABR_REGISTRY",
    "PABR_TARGET",
    "pabr_track_names",
    "PABR_URL",
    "PABR_USER",
    "pabr_vectors",
    "PabrVectors",
    "RSSI_MAX_DBM",
    "RSSI_MIN_DBM",
    "SUBSET_SPAN_PACKETS",
]
