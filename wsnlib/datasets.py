"""Old home of the IMU recording format and the BROAD loader; the code now lives in :mod:`wsnlib.io`.

* :mod:`wsnlib.io.recording`: :class:`Recording`, :func:`write_recording`, :func:`read_recording`
  and the sidecar writer/reader shared by every CSV + JSON format;
* :mod:`wsnlib.io.broad`: the BROAD registry, download and :func:`load_broad`;
* :mod:`wsnlib.io.download`: :class:`RegistryEntry` and the verified download.

Every name is re-exported here (the same objects), so ``wsnlib.datasets.load_broad`` and the
other old import paths keep working.  New code imports from :mod:`wsnlib.io`.
"""

# Re-exports (the same objects).  _broad_trial_name and sha256_of are not API (hence outside
# __all__), but existing code and tests reach them through this old path.
from wsnlib.io.broad import (  # noqa: F401
    BROAD_COMMIT,
    BROAD_DIR_ENV_VAR,
    BROAD_REGISTRY,
    BROAD_URL,
    BroadTrial,
    _broad_trial_name,
    broad_dir,
    broad_file,
    broad_trial_info,
    broad_trial_numbers,
    broad_trials,
    load_broad,
    sha256_of,
)
from wsnlib.io.download import (
    RegistryEntry,
    download_verified,
    git_blob_sha1_of,
)
from wsnlib.io.recording import (
    ALL_COLUMNS,
    BASE_COLUMNS,
    CSV_ROWS_KEY,
    CSV_SHA256_KEY,
    FLOAT_FORMAT,
    FORMAT_NAME,
    FORMAT_VERSION,
    FRAME_CONVENTION,
    QUAT_COLUMNS,
    SIGNAL_COLUMNS,
    UNITS,
    Recording,
    check_sidecar_units,
    finite_column,
    load_sidecar,
    read_recording,
    sidecar_path,
    write_recording,
    write_table_with_sidecar,
)

__all__ = [
    "ALL_COLUMNS",
    "BASE_COLUMNS",
    "BROAD_COMMIT",
    "broad_dir",
    "BROAD_DIR_ENV_VAR",
    "broad_file",
    "BROAD_REGISTRY",
    "broad_trial_info",
    "broad_trial_numbers",
    "broad_trials",
    "BROAD_URL",
    "BroadTrial",
    "check_sidecar_units",
    "CSV_ROWS_KEY",
    "CSV_SHA256_KEY",
    "download_verified",
    "finite_column",
    "FLOAT_FORMAT",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "FRAME_CONVENTION",
    "git_blob_sha1_of",
    "load_broad",
    "load_sidecar",
    "QUAT_COLUMNS",
    "read_recording",
    "Recording",
    "RegistryEntry",
    "sidecar_path",
    "SIGNAL_COLUMNS",
    "UNITS",
    "write_recording",
    "write_table_with_sidecar",
]
