"""Old home of the RSS recording format and fingerprint vectors; the code now lives in :mod:`wsnlib.io.rss`.

Every name is re-exported here (the same objects), so ``wsnlib.rss.*`` keeps working. New code
imports from :mod:`wsnlib.io.rss`.

What the old module imported and so also offered (the sidecar helpers of :mod:`wsnlib.io.recording`
and the testbed names) stays importable from here, outside ``__all__``.
"""

from wsnlib.io.recording import (  # noqa: F401
    check_sidecar_units,
    finite_column,
    load_sidecar,
    sidecar_path,
    write_table_with_sidecar,
)
from wsnlib.io.rss import (
    COLUMNS,
    DEFAULT_FLOOR_DBM,
    FLOAT_COLUMNS,
    FLOAT_FORMAT,
    FORMAT_NAME,
    FORMAT_VERSION,
    FRAME,
    RSS_RANGE_DBM,
    TEXT_COLUMNS,
    UNITS,
    RssVectors,
    read_rss,
    rss_vectors,
    write_rss,
)
from wsnlib.testbed import ANCHOR_NAMES, TARGET_NAMES  # noqa: F401

__all__ = [
    "COLUMNS",
    "DEFAULT_FLOOR_DBM",
    "FLOAT_COLUMNS",
    "FLOAT_FORMAT",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "FRAME",
    "read_rss",
    "RSS_RANGE_DBM",
    "rss_vectors",
    "RssVectors",
    "TEXT_COLUMNS",
    "UNITS",
    "write_rss",
]
