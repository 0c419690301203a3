"""Earth-frame reference vectors (ENU: x east, y north, z up) shared by simulator and filters.

The defaults describe the paper's site, Benevento, Italy (41.13° N, 14.78° E).  Values from
the World Magnetic Model WMM2020 for 2020.0 at that location: total intensity ≈ 46 µT,
inclination (dip, field pointing below the horizon) ≈ 57°.  Declination (≈ 4° E) is ignored:
the simulator's "north" is magnetic north, which is what TRIAD and Madgwick's filter align to.
"""

from __future__ import annotations

import numpy as np

#: Standard gravity (m/s²), ISO 80000-3.
STANDARD_GRAVITY = 9.80665

#: Earth magnetic field intensity at the paper's site (µT), WMM2020.
MAGNETIC_INTENSITY_UT = 46.0

#: Magnetic inclination (dip) at the paper's site (degrees below the horizon), WMM2020.
MAGNETIC_DIP_DEG = 57.0


def gravity_specific_force_enu(gravity: float = STANDARD_GRAVITY) -> np.ndarray:
    """What an accelerometer at rest reads, in the earth frame (m/s²): ``[0, 0, +g]``."""
    return np.array([0.0, 0.0, gravity])


def magnetic_field_enu(intensity_ut: float = MAGNETIC_INTENSITY_UT, dip_deg: float = MAGNETIC_DIP_DEG) -> np.ndarray:
    """Earth magnetic field in ENU (µT): horizontal part towards north, dipping below the horizon."""
    dip = np.radians(dip_deg)
    return intensity_ut * np.array([0.0, np.cos(dip), -np.sin(dip)])
