"""The CSV + JSON sidecar machinery every recording format of :mod:`wsnlib.io` shares.

A recording file is ``<name>.csv`` plus ``<name>.json`` (the sidecar).  The formats
(:mod:`wsnlib.io.recording` for IMU recordings, :mod:`wsnlib.io.rss`, :mod:`wsnlib.io.accel`)
define their columns and sidecar keys; this module writes both files byte-reproducibly and
atomically (:func:`write_table_with_sidecar`), and reads a CSV with its checked sidecar
(:func:`read_table`; :func:`load_sidecar`: format name and version, and the CSV's row count and
SHA-256 — :data:`CSV_ROWS_KEY`, :data:`CSV_SHA256_KEY` — so a truncated or edited CSV is refused).
The checks every format applies to its columns live here too: numbers (:func:`finite_column`)
and names (:func:`check_name`, :func:`check_names`, :func:`name_column`: non-empty, without
commas, quotes, line breaks or surrounding spaces).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pandas as pd

from wsnlib._files import atomic_write_bytes, atomic_write_text

#: Sidecar keys written by every recording format (:func:`write_table_with_sidecar`): the
#: number of data rows of the CSV and the SHA-256 of its bytes, checked by the readers.
CSV_ROWS_KEY = "csv_rows"
CSV_SHA256_KEY = "csv_sha256"


def sidecar_path(path) -> Path:
    """The JSON sidecar that belongs to CSV ``path``: same name, suffix ``.json``."""
    return Path(path).with_suffix(".json")


def _json_default(value):
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (tuple, set, frozenset)):
        return list(value)
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def write_table_with_sidecar(frame, path, sidecar: dict, float_format: str, what: str = "metadata") -> Path:
    """Write ``frame`` as CSV and ``sidecar`` as ``<name>.json`` (sorted keys), byte-reproducibly.

    Shared by the recording formats of :mod:`wsnlib.io.recording`, :mod:`wsnlib.io.rss` and
    :mod:`wsnlib.io.accel`.  ``what`` names the user-supplied part in the error raised
    when the sidecar is not JSON-serialisable.  The sidecar gains :data:`CSV_ROWS_KEY` (the
    number of data rows) and :data:`CSV_SHA256_KEY` (the SHA-256 of the CSV's bytes), which
    :func:`load_sidecar` checks, so a truncated or altered copy is refused.  Both files are
    written atomically (temporary file + rename), the CSV first.  ``path`` must name the CSV,
    not the sidecar (``ValueError``).
    """
    path = Path(path)
    if path.suffix.lower() == ".json":
        raise ValueError(f"path must name the CSV file, not the sidecar: {path}")
    csv_bytes = frame.to_csv(None, index=False, float_format=float_format, lineterminator="\n").encode("utf-8")
    sidecar = {**sidecar, CSV_ROWS_KEY: len(frame), CSV_SHA256_KEY: hashlib.sha256(csv_bytes).hexdigest()}
    try:
        text = json.dumps(sidecar, indent=2, sort_keys=True, default=_json_default, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} cannot be written as JSON: {exc}") from exc
    atomic_write_bytes(path, csv_bytes)
    atomic_write_text(sidecar_path(path), text + "\n")
    return path


def _check_csv_integrity(path: Path, meta: dict, side: Path) -> None:
    """Compare the CSV with the row count and SHA-256 its sidecar recorded (when it has them)."""
    if CSV_ROWS_KEY not in meta and CSV_SHA256_KEY not in meta:
        return  # a hand-converted file: nothing to check against
    rows, digest = meta.get(CSV_ROWS_KEY), meta.get(CSV_SHA256_KEY)
    if isinstance(rows, bool) or not isinstance(rows, int) or rows < 0:
        raise ValueError(f"{side}: {CSV_ROWS_KEY!r} must be a non-negative integer, got {rows!r}")
    if not isinstance(digest, str) or len(digest) != 64 or any(c not in "0123456789abcdef" for c in digest):
        raise ValueError(f"{side}: {CSV_SHA256_KEY!r} must be 64 lower-case hex digits, got {digest!r}")
    data = path.read_bytes()
    lines = data.count(b"\n") + (1 if data and not data.endswith(b"\n") else 0)
    found = max(lines - 1, 0)  # minus the header line
    if found != rows:
        raise ValueError(f"{path}: has {found} data rows but its sidecar {side.name} says {rows}: the file is "
                         f"truncated or was changed after it was written (write it again with the writer)")
    actual = hashlib.sha256(data).hexdigest()
    if actual != digest:
        raise ValueError(f"{path}: SHA-256 {actual[:12]}… differs from {CSV_SHA256_KEY!r} {digest[:12]}… in its "
                         f"sidecar {side.name}: the file was damaged or changed after it was written (write it again "
                         f"with the writer)")


def finite_column(frame, column: str, where) -> np.ndarray:
    """Column ``column`` of a read CSV table as finite floats, or ``ValueError`` naming file, column and row."""
    values = pd.to_numeric(frame[column], errors="coerce").to_numpy(dtype=float)
    bad = ~np.isfinite(values)
    if np.any(bad):
        row = int(np.argmax(bad))
        raise ValueError(f"{where}: column {column!r} has a non-numeric or non-finite value "
                         f"{frame[column].iloc[row]!r} at data row {row + 1}")
    return values


def check_name(value, what: str) -> str:
    """``value`` if it is a usable name (non-empty, no commas, quotes or surrounding spaces), else ``ValueError``."""
    if not isinstance(value, str) or not value or value != value.strip() or any(c in value for c in ',"\n\r'):
        raise ValueError(f"{what} must be a non-empty string without commas, quotes or surrounding spaces, "
                         f"got {value!r}")
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


def name_column(frame, column: str, where) -> np.ndarray:
    """Column ``column`` of a read table as names (object array): each a non-empty string without
    commas, quotes, line breaks or surrounding spaces, or ``ValueError`` naming file, column and row."""
    values = frame[column].to_numpy(dtype=object)
    codes, uniques = pd.factorize(values, use_na_sentinel=False)
    for code, value in enumerate(uniques):  # check each distinct name once
        if not isinstance(value, str) or not value or any(c in value for c in ',"\n\r') or value != value.strip():
            row = int(np.argmax(codes == code))
            raise ValueError(f"{where}: column {column!r} has an empty or invalid name {value!r} at data row {row + 1}")
    return values


def check_columns(df, columns, where) -> None:
    """``ValueError`` naming ``where`` unless ``df`` is a DataFrame with exactly ``columns``, in order, and rows."""
    if not isinstance(df, pd.DataFrame):
        raise ValueError(f"{where}: expected a pandas DataFrame, got {type(df).__name__}")
    got, columns = list(df.columns), list(columns)
    missing = [c for c in columns if c not in got]
    if missing:
        raise ValueError(f"{where}: missing column(s) {missing}; expected the columns {columns}")
    unknown = [c for c in got if c not in columns]
    if unknown:
        raise ValueError(f"{where}: unknown column(s) {unknown}; expected the columns {columns}")
    if got != columns:
        raise ValueError(f"{where}: columns must be in the order {columns}, got {got}")
    if len(df) == 0:
        raise ValueError(f"{where}: has no data rows")


def block_order(frame: pd.DataFrame) -> np.ndarray:
    """Block index per row of a long table: (user, session) pairs numbered in order of first appearance."""
    return pd.factorize(frame["user"].astype(str) + "\x1f" + frame["session"].astype(str), sort=False)[0]


def _row_keys(frame: pd.DataFrame, orders: dict) -> np.ndarray:
    """Per row: block, ``time_s``, then the rank of each column of ``orders`` in its list of names."""
    ranks = [frame[column].map({name: i for i, name in enumerate(names)}).to_numpy()
             for column, names in orders.items()]
    return np.stack([block_order(frame), frame["time_s"].to_numpy(), *ranks], axis=1)


def sort_rows(frame: pd.DataFrame, orders: dict) -> pd.DataFrame:
    """Rows in file order: (user, session) blocks in order of appearance, then time, then each column
    of ``orders`` (``{column: names}``) in the order of its names."""
    return frame.iloc[np.lexsort(_row_keys(frame, orders).T[::-1])].reset_index(drop=True)


def check_order(frame: pd.DataFrame, orders: dict, where, duplicate: str) -> np.ndarray:
    """``ValueError`` naming ``where``, the column and the data row unless ``frame`` is in the file order
    of :func:`sort_rows` without two rows of equal key (``duplicate`` says what such a pair is).

    Returns, per pair of consecutive rows, whether they share block, time and every column of
    ``orders`` but the last (the rows of one packet, for the per-packet checks of a format).
    """
    key = _row_keys(frame, orders)
    step = key[1:] - key[:-1]
    if np.any(step[:, 0] < 0):
        row = int(np.argmax(step[:, 0] < 0)) + 1
        raise ValueError(f"{where}: column 'session': rows of each (user, session) must be contiguous; data row "
                         f"{row + 1} returns to an earlier block")
    same_block = step[:, 0] == 0
    # Lexicographic comparison of consecutive rows within a block.
    first_nonzero = np.argmax(step[:, 1:] != 0, axis=1)
    sign = np.sign(step[np.arange(len(step)), 1 + first_nonzero])
    all_zero = ~np.any(step[:, 1:] != 0, axis=1)
    bad_order = same_block & ~all_zero & (sign < 0)
    if np.any(bad_order):
        row = int(np.argmax(bad_order)) + 1
        raise ValueError(f"{where}: column 'time_s': rows must be ordered by {', '.join(['time', *orders])} within "
                         f"each (user, session); data row {row + 1} is out of order")
    if np.any(same_block & all_zero):
        row = int(np.argmax(same_block & all_zero)) + 1
        raise ValueError(f"{where}: column {list(orders)[-1]!r}: duplicate {duplicate} at data row {row + 1}")
    return same_block & ~np.any(step[:, 1:-1] != 0, axis=1)


def load_sidecar(path: Path, format_name: str, format_version: int, *, required: bool, what: str,
                 older_versions: tuple[int, ...] = ()) -> dict | None:
    """Read and check the ``<name>.json`` sidecar of a recording file (format name and version).

    The version must be ``format_version`` (the newest the reader knows) or one of
    ``older_versions`` (those it still reads).  Returns None when it is missing and not
    ``required``; raises ``ValueError`` naming the sidecar otherwise (``what`` says which kind of
    file needs it).  When the sidecar records
    :data:`CSV_ROWS_KEY` and :data:`CSV_SHA256_KEY` (every file the writers produce), the CSV
    ``path`` must have that many data rows and that SHA-256, else ``ValueError`` naming the
    file (truncated or changed after writing).  A hand-made sidecar may leave both out.
    """
    side = sidecar_path(path)
    if not side.exists():
        if required:
            raise ValueError(f"{side}: missing sidecar ({what} needs its .json file)")
        return None
    try:
        meta = json.loads(side.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{side}: not valid JSON ({exc})") from exc
    if not isinstance(meta, dict):
        raise ValueError(f"{side}: must hold a JSON object")
    if meta.get("format") != format_name:
        raise ValueError(f"{side}: 'format' must be {format_name!r}, got {meta.get('format')!r}")
    known = (*older_versions, format_version)
    version = meta.get("format_version")
    if isinstance(version, bool) or version not in known:
        raise ValueError(f"{side}: unsupported 'format_version' {version!r} (this reader knows "
                         f"{' and '.join(str(v) for v in known)})")
    _check_csv_integrity(Path(path), meta, side)
    return meta


def check_sidecar_units(meta: dict, units: dict, side: Path) -> None:
    """``ValueError`` naming the sidecar unless ``meta["units"]`` gives every unit of ``units`` as documented."""
    found = meta.get("units")
    if not isinstance(found, dict):
        raise ValueError(f"{side}: 'units' must be an object {units}, got {found!r}")
    for key, unit in units.items():
        if found.get(key) != unit:
            raise ValueError(f"{side}: units[{key!r}] must be {unit!r} (convert the data first), "
                             f"got {found.get(key)!r}")


def read_table(path, format_name: str, format_version: int, *, what: str, required: bool = True, keys=(),
               units: dict | None = None, older_versions: tuple[int, ...] = (),
               **csv_options) -> tuple[dict | None, pd.DataFrame]:
    """Read the CSV ``path`` of a recording file and its checked sidecar: ``(sidecar or None, table)``.

    The sidecar is checked by :func:`load_sidecar` (``required``, ``what``, ``older_versions``), must hold every
    key of ``keys`` and, if given, the ``units`` (:func:`check_sidecar_units`); its
    ``metadata`` (default ``{}``) must be an object.  The CSV is read by :func:`pandas.read_csv`
    with ``csv_options`` (default: every column as text, no NA parsing, for the format's own
    checks).  ``ValueError`` naming the file: none there, a bad sidecar, a CSV that cannot be
    parsed.
    """
    path = Path(path)
    if not path.exists():
        raise ValueError(f"{path}: no such file")
    meta = load_sidecar(path, format_name, format_version, required=required, what=what,
                        older_versions=older_versions)
    if meta is not None:
        side = sidecar_path(path)
        for key in keys:
            if key not in meta:
                raise ValueError(f"{side}: missing key {key!r}")
        if units is not None:
            check_sidecar_units(meta, units, side)
        if not isinstance(meta.setdefault("metadata", {}), dict):
            raise ValueError(f"{side}: 'metadata' must be an object")
    try:
        table = pd.read_csv(path, **(csv_options or {"dtype": str, "keep_default_na": False, "na_filter": False}))
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot be parsed as CSV ({exc})") from exc
    return meta, table
