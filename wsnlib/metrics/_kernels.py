"""Compiled elementwise steps of the orientation metrics, with numpy's bits.

A study scores every method on whole recordings under many loss masks; numpy spends most of that
time on temporaries (a Hamilton product alone makes 28 of them) and on strided components.  These
loops do the elementwise arithmetic row by row instead.  Each value is the same expression,
evaluated left to right as numpy evaluates it (no fused multiply-add: numba does not contract
without ``fastmath``), and a sum of squares over a row's 3 or 4 components runs left to right as
:func:`numpy.linalg.norm` and :func:`numpy.sum` do over so short an axis; ``math.hypot`` is the C
library's, as :func:`numpy.hypot` is.  The arc tangents stay with numpy (:func:`numpy.arctan2` has
CPU-specific versions that differ from the C library's in the last bit), and so do the sums over
time.  So the metrics give the same bits as the numpy expressions they replace
(``tests/test_metrics.py`` compares them bit for bit).

The Hamilton product is written out here rather than calling :mod:`wsnlib.quaternion`'s compiled one:
numba caches a function with the machine code of what it calls, keyed on its own file only, so a
kernel calling into another file would keep running that file's old code after it changed.
"""

from __future__ import annotations

import math

from numba import njit

COMPILE = {"cache": True, "error_model": "numpy"}


@njit(**COMPILE)
def error_angle_arguments(est, ref, out):
    """For estimates ``est`` (M, T, 4) and references ``ref`` (R, T, 4), R = 1 (one reference for every
    row of ``est``) or M, the error quaternions ``e = est ⊗ ref*`` ``[w, x, y, z]`` and the arguments of
    BROAD's three ``atan2`` forms into ``out`` (5, M, T): ``‖(x, y, z)‖``, ``|w|``, ``|z|``,
    ``hypot(x, y)``, ``hypot(w, z)`` (:func:`wsnlib.metrics.broad_errors_deg`).  ``ref*`` is
    ``ref · [1, −1, −1, −1]``, as :func:`wsnlib.quaternion.conjugate` forms it; the error quaternions
    are not stored, and one reference is not copied per row of ``est``."""
    one_ref = ref.shape[0] == 1
    for m in range(est.shape[0]):
        r = ref[0 if one_ref else m]
        for t in range(est.shape[1]):
            pw, px, py, pz = est[m, t, 0], est[m, t, 1], est[m, t, 2], est[m, t, 3]
            qw, qx, qy, qz = r[t, 0] * 1.0, r[t, 1] * -1.0, r[t, 2] * -1.0, r[t, 3] * -1.0
            w = pw * qw - px * qx - py * qy - pz * qz
            x = pw * qx + px * qw + py * qz - pz * qy
            y = pw * qy - px * qz + py * qw + pz * qx
            z = pw * qz + px * qy - py * qx + pz * qw
            out[0, m, t] = math.sqrt(x * x + y * y + z * z)
            out[1, m, t] = abs(w)
            out[2, m, t] = abs(z)
            out[3, m, t] = math.hypot(x, y)
            out[4, m, t] = math.hypot(w, z)


@njit(**COMPILE)
def rotation_steps(quat, vector, sin_half, cos_half):
    """Each step between consecutive quaternions of ``quat`` (M, T, 4): ``δ_t = q_t* ⊗ q_{t+1}``
    with ``w ≥ 0`` (the shorter way), its vector part into ``vector`` (M, T − 1, 3), ``‖vector‖`` =
    sin(angle/2) into ``sin_half`` and ``w`` = cos(angle/2) into ``cos_half`` (M, T − 1)
    (:func:`wsnlib.metrics.angular_jerk_rms_deg`)."""
    for m in range(quat.shape[0]):
        for t in range(quat.shape[1] - 1):
            # q_t* = q_t · [1, −1, −1, −1] (as wsnlib.quaternion.conjugate), then the Hamilton product
            pw, px, py, pz = quat[m, t, 0] * 1.0, quat[m, t, 1] * -1.0, quat[m, t, 2] * -1.0, quat[m, t, 3] * -1.0
            qw, qx, qy, qz = quat[m, t + 1, 0], quat[m, t + 1, 1], quat[m, t + 1, 2], quat[m, t + 1, 3]
            w = pw * qw - px * qx - py * qy - pz * qz
            x = pw * qx + px * qw + py * qz - pz * qy
            y = pw * qy - px * qz + py * qw + pz * qx
            z = pw * qz + px * qy - py * qx + pz * qw
            if w < 0.0:  # canonical: −δ is the same rotation
                w, x, y, z = -w, -x, -y, -z
            vector[m, t, 0], vector[m, t, 1], vector[m, t, 2] = x, y, z
            sin_half[m, t] = math.sqrt(x * x + y * y + z * z)
            cos_half[m, t] = w


@njit(**COMPILE)
def squared_jerk(vector, sin_half, angle, fs, fs2, out):
    """``‖j_t‖²`` (rad²/s⁶) into ``out`` (M, T − 3) from :func:`rotation_steps`' ``vector`` and
    ``sin_half`` and the steps' angles ``angle`` (M, T − 1; rad): the rate ``ω_t = axis_t · angle_t
    · fs`` (axis 0 for a step of no rotation), its second difference ``(ω_{t+2} − ω_{t+1}) − (ω_{t+1}
    − ω_t)``, times ``fs2`` = fs²."""
    for m in range(out.shape[0]):
        for t in range(out.shape[1]):
            total = 0.0
            for a in range(3):
                w0 = _rate(vector, sin_half, angle, fs, m, t, a)
                w1 = _rate(vector, sin_half, angle, fs, m, t + 1, a)
                w2 = _rate(vector, sin_half, angle, fs, m, t + 2, a)
                j = ((w2 - w1) - (w1 - w0)) * fs2
                total = j * j if a == 0 else total + j * j
            out[m, t] = total


@njit(inline="always", **COMPILE)
def _rate(vector, sin_half, angle, fs, m, t, a):
    s = sin_half[m, t]
    axis = vector[m, t, a] / s if s > 0.0 else 0.0
    return axis * angle[m, t] * fs
