"""Old home of the PABR dataset loader; the code now lives in :mod:`wsnlib.io.pabr`.

Every name is re-exported here (the same objects), so ``wsnlib.pabr.*`` keeps working. New code
imports from :mod:`wsnlib.io.pabr`; ``PabrVectors`` is the one RSS vector type,
:class:`wsnlib.io.vectors.RssVectors`.
"""

from wsnlib.io.pabr import (
    FINGERPRINT_SETS,
    PABR_COMMIT,
    PABR_DIR_ENV_VAR,
    PABR_REGISTRY,
    PABR_TARGET,
    PABR_URL,
    PABR_USER,
    RSSI_MAX_DBM,
    RSSI_MIN_DBM,
    SUBSET_SPAN_PACKETS,
    PabrVectors,
    load_pabr_fingerprints,
    load_pabr_receivers,
    load_pabr_tracks,
    pabr_dir,
    pabr_file,
    pabr_track_names,
    pabr_vectors,
)

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
