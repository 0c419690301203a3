"""Orientation estimators: Madgwick's filter (data fusion) and TRIAD (single frame).

All take body-frame signals ``(..., T, 3)`` and return ENU quaternions ``(..., T, 4)``
(see :mod:`wsnlib` for the conventions).  :mod:`.loss_handling` adds paper 001's hybrid
SLERP (eqs. (3)–(4)) and the loss-handling alternatives of its Sec. V.
"""

from wsnlib.orientation.loss_handling import effective_lost_run, estimate_orientation, slerp_weight
from wsnlib.orientation.madgwick import madgwick, madgwick_step
from wsnlib.orientation.triad import tilt_quaternion, triad

__all__ = [
    "effective_lost_run",
    "estimate_orientation",
    "madgwick",
    "madgwick_step",
    "slerp_weight",
    "tilt_quaternion",
    "triad",
]
