"""Orientation estimators: Madgwick's filter (data fusion) and TRIAD (single frame).

All take body-frame signals ``(..., T, 3)`` and return ENU quaternions ``(..., T, 4)``
(see :mod:`wsnlib` for the conventions).
"""

from wsnlib.orientation.madgwick import madgwick, madgwick_step
from wsnlib.orientation.triad import tilt_quaternion, triad

__all__ = ["madgwick", "madgwick_step", "tilt_quaternion", "triad"]
