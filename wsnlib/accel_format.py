"""Old home of the accelerometer and Kinect sample-table format; the code now lives in :mod:`wsnlib.io.accel`.

Every name is re-exported here (the same objects), so ``wsnlib.accel_format.*`` keeps working. New
code imports from :mod:`wsnlib.io.accel`.

What the old module imported and so also offered (the sidecar helpers of :mod:`wsnlib.io.recording`
and ``TARGET_NAMES``) stays importable from here, outside ``__all__``.
"""

from wsnlib.io.accel import (
    FLOAT_FORMAT,
    FORMAT_NAME,
    FORMAT_VERSION,
    FRAMES,
    KEY_COLUMNS,
    KINDS,
    TEXT_COLUMNS,
    UNITS,
    VALUE_COLUMNS,
    columns,
    read_acc,
    read_kinect,
    read_samples,
    write_acc,
    write_kinect,
    write_samples,
)
from wsnlib.io.recording import (  # noqa: F401
    check_sidecar_units,
    finite_column,
    load_sidecar,
    sidecar_path,
    write_table_with_sidecar,
)
from wsnlib.testbed import TARGET_NAMES  # noqa: F401

__all__ = [
    "columns",
    "FLOAT_FORMAT",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "FRAMES",
    "KEY_COLUMNS",
    "KINDS",
    "read_acc",
    "read_kinect",
    "read_samples",
    "TEXT_COLUMNS",
    "UNITS",
    "VALUE_COLUMNS",
    "write_acc",
    "write_kinect",
    "write_samples",
]
