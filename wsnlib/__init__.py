"""wsnlib: the helper library behind the wsn-motion notebooks.

Conventions, stated once for the whole package
----------------------------------------------
* Quaternions are numpy arrays ``[..., 4]``, scalar first ``[w, x, y, z]``.  A quaternion
  ``q`` rotates a body-frame (sensor) vector into the earth frame: ``v_E = q ⊗ v_B ⊗ q*``.
  The earth frame is ENU: x east, y north, z up.  This is the convention of BROAD's
  ``opt_quat`` and of ``scipy.spatial.transform.Rotation`` (which stores the scalar last;
  :mod:`wsnlib.quaternion` is the only place that reorders).
* Signals: ``gyr`` rad/s, ``acc`` m/s² (specific force: +g along earth z at rest),
  ``mag`` µT, time in seconds, ``fs`` in Hz.
* Arrays have shape ``(..., T, 3)`` (vectors) or ``(..., T, 4)`` (quaternions); leading
  dimensions are batches (Monte Carlo runs, parameter grids).
* Packet loss is a boolean ``received`` mask of shape ``(..., T)``; rows are never deleted.
* Every random draw comes from a ``numpy.random.Generator`` passed in as ``rng``.
"""

__version__ = "0.1.0"

from pathlib import Path as _Path

from wsnlib._files import sources_digest as _sources_digest

#: SHA-256 of wsnlib's ``.py`` sources when this process imported the package: :mod:`wsnlib.cache`
#: keys results by it, so a kernel still running old code never files a result under an edited
#: source's key (it is read once, here, not when the first result is stored).
SOURCE_DIGEST = _sources_digest(_Path(__file__).parent)
