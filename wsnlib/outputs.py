"""Tables the notebooks write: one call, like :func:`wsnlib.plotting.savefig` for figures.

:func:`save_table` writes ``data/processed/<name>.csv`` (below ``$WSNLIB_OUTPUT_DIR`` when it
is set) through a temporary file in the same folder, renamed into place: a batch killed
while writing leaves the previous table or none, never a truncated one.
"""

from __future__ import annotations

from pathlib import Path

from wsnlib import paths
from wsnlib._files import write_csv


def save_table(frame, name: str, **to_csv_kwargs) -> Path:
    """Write ``frame`` (a pandas DataFrame or Series) to ``data/processed/<name>.csv`` atomically.

    Parameters
    ----------
    frame : pandas.DataFrame or pandas.Series
    name : str
        File stem, e.g. ``"a05_rmse_overall"``; letters, digits, ``_`` and ``-`` only.
    **to_csv_kwargs
        Passed to ``frame.to_csv`` (``index=False``, ``index_label=…``).

    Returns
    -------
    pathlib.Path
        The file written.
    """
    if not name or not all(ch.isalnum() or ch in "_-" for ch in name):
        raise ValueError(f"name must be a plain file stem (letters, digits, _ or -), got {name!r}")
    if not hasattr(frame, "to_csv"):
        raise ValueError(f"frame must be a pandas DataFrame or Series, got {type(frame).__name__}")
    return write_csv(frame, paths.data_processed() / f"{name}.csv", **to_csv_kwargs)
