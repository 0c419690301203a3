"""Old home of the resampling of recordings; the code now lives in :mod:`wsnlib.io.resample`.

Every name is re-exported here (the same objects), so ``wsnlib.resample.*`` keeps working. New code
imports from :mod:`wsnlib.io.resample`.

What the old module imported and so also offered (``BroadTrial``) stays importable from here,
outside ``__all__``.
"""

from wsnlib.io.broad import BroadTrial  # noqa: F401
from wsnlib.io.resample import (
    MAX_DENOMINATOR,
    n_resampled,
    resample_broad,
    resample_factors,
    resample_mask,
    resample_quaternion,
    resample_signal,
    resampled_times,
)

__all__ = [
    "MAX_DENOMINATOR",
    "n_resampled",
    "resample_broad",
    "resample_factors",
    "resample_mask",
    "resample_quaternion",
    "resample_signal",
    "resampled_times",
]
