"""x-io Fusion's update over a run of samples: imufusion's own C function, called from a compiled loop.

``imufusion`` (1.3.x) has no batch call: ``Ahrs.update`` from Python costs about 1 µs per sample
(argument parsing, a new array per quaternion) around about 0.1 µs of C.  Its extension module
exports the C library's functions (``FusionAhrsUpdate``, ``FusionAhrsUpdateNoMagnetometer``), and
an ``imufusion.Ahrs`` object holds the C struct ``FusionAhrs`` right after its Python object header
(``typedef struct { PyObject_HEAD FusionAhrs wrapped; } Ahrs``, the package's ``Ahrs.h``).  So
:class:`FusionUpdates` calls those very functions on that very struct from a numba loop: the same
machine code on the same state, hence bit for bit what ``Ahrs.update`` gives, and ``Ahrs``'s
Python methods (``set_quaternion`` at a gap's end) still act on the state the loop updates.

How the arguments travel (x86-64 System V: Linux, macOS on Intel).  ``FusionVector`` (three
floats, 12 bytes) is passed by value, in two SSE registers: ``(x, y)`` as one 8-byte lane and ``z``
alone.  Each vector is therefore given as a double whose 8 bytes are the floats ``x, y`` (the
registers carry bits, no arithmetic touches them) and a float ``z``: :func:`_lanes` packs a
recording once.  The quaternion is read from the struct after each update (``FusionAhrsGetQuaternion``
returns it from there; its offset is found, not assumed: :func:`_native_calls`).

Checked, not trusted: before first use the compiled loop and ``Ahrs.update`` run the same short
recording (rejection, start-up ramp, ``set_quaternion`` mid-way, zeros in the inputs) and must
agree bit for bit.  Elsewhere than CPython on x86-64 System V every update goes through ``Ahrs.update`` from
Python (the same results, slower), and so, with a warning, with an imufusion other than
:data:`CHECKED_VERSIONS`, without the exported functions, or when the two do not agree.
``tests/test_peers.py`` checks both paths against each other.
"""

from __future__ import annotations

import ctypes
import functools
import importlib.metadata
import platform
import sys

import imufusion
import numpy as np
from numba import njit

from wsnlib._gc_pause import paused_collector
from wsnlib._user_warnings import warn_user
from wsnlib.orientation._scalar_kernels import COMPILE, quat_normalize, slerp

#: imufusion versions whose C functions take the arguments described above (checked on each at first use).
CHECKED_VERSIONS = ("1.3.",)
#: Bytes of the Python object header (``PyObject_HEAD``) that the C struct ``FusionAhrs`` follows.
_HEADER_BYTES = object.__basicsize__
_STRUCT_BYTES = imufusion.Ahrs.__basicsize__ - _HEADER_BYTES

#: ``void FusionAhrsUpdate(FusionAhrs *, FusionVector gyroscope, FusionVector accelerometer,
#: FusionVector magnetometer)`` and ``…NoMagnetometer`` without the last: the struct's address as a
#: pointer-sized integer (the same register as a pointer), each vector as its (x, y) lane and z.
_VECTOR = (ctypes.c_double, ctypes.c_float)
_UPDATE_9D = ctypes.CFUNCTYPE(None, ctypes.c_size_t, *_VECTOR * 3)
_UPDATE_6D = ctypes.CFUNCTYPE(None, ctypes.c_size_t, *_VECTOR * 2)


@njit(**COMPILE)
def _blend(state, q_at, out, t, q_s, mu):
    """Paper 001's feedback hybrid on sample ``t``: ``out[t] ← SLERP(q_s, out[t] normalised, μ)`` (eq. (4),
    :func:`~wsnlib.orientation._scalar_kernels.slerp`), and the filter continues from it (as
    ``Ahrs.set_quaternion``: the struct's quaternion, in float)."""
    q = slerp((q_s[0], q_s[1], q_s[2], q_s[3]), quat_normalize((out[t, 0], out[t, 1], out[t, 2], out[t, 3])), mu)
    for i in range(4):
        out[t, i] = q[i]
        state[q_at + i] = np.float32(q[i])


@njit(**COMPILE)
def _run_9d(update, ahrs, state, q_at, gyr, acc, mag, out, start, end, blend_at, q_s, mu):
    """``update(ahrs, gyroscope, accelerometer, magnetometer)`` for samples ``start … end − 1`` (rows of
    :func:`_lanes`), the quaternion ``state[q_at : q_at + 4]`` after each into ``out[t]``; on samples
    ``blend_at`` (``(T,)`` bool, or ``(0,)``: none) the feedback hybrid :func:`_blend` with ``q_s[t]``, ``mu[t]``."""
    for t in range(start, end):
        update(ahrs, gyr[t, 0], gyr[t, 1], acc[t, 0], acc[t, 1], mag[t, 0], mag[t, 1])
        for i in range(4):
            out[t, i] = state[q_at + i]
        if blend_at.size and blend_at[t]:
            _blend(state, q_at, out, t, q_s[t], mu[t])


@njit(**COMPILE)
def _run_6d(update, ahrs, state, q_at, gyr, acc, out, start, end, blend_at, q_s, mu):
    """:func:`_run_9d` without magnetometer (``FusionAhrsUpdateNoMagnetometer``)."""
    for t in range(start, end):
        update(ahrs, gyr[t, 0], gyr[t, 1], acc[t, 0], acc[t, 1])
        for i in range(4):
            out[t, i] = state[q_at + i]
        if blend_at.size and blend_at[t]:
            _blend(state, q_at, out, t, q_s[t], mu[t])


def _lanes(x: np.ndarray) -> np.ndarray:
    """``(T, 2)`` float64: a ``(T, 3)`` signal as its ``FusionVector`` travels, column 0 the 8 bytes of
    the floats (x, y), column 1 the float z (exact in a double).  The conversion to float is C's
    ``(float)`` cast (round to nearest), as imufusion's own."""
    x32 = np.asarray(x, dtype=np.float32)
    lanes = np.empty((x32.shape[0], 2))
    lanes[:, 0] = np.ascontiguousarray(x32[:, :2]).view(np.float64)[:, 0]
    lanes[:, 1] = x32[:, 2]
    return lanes


def _struct_floats(ahrs: imufusion.Ahrs) -> np.ndarray:
    """The ``FusionAhrs`` struct of ``ahrs`` as float32 words (a view: valid while ``ahrs`` lives)."""
    words = _STRUCT_BYTES // 4
    return np.frombuffer((ctypes.c_float * words).from_address(id(ahrs) + _HEADER_BYTES), dtype=np.float32)


#: :class:`FusionUpdates`' default ``native``: the checked C functions where they apply (:func:`_native_calls`).
CHECKED = "checked"


class FusionUpdates:
    """Fusion's updates of one recording: :meth:`run` feeds ``ahrs`` the samples ``start … end − 1`` and
    writes its quaternion after each into ``out``.

    ``gyr_deg`` (°/s), ``acc_g`` (g) and ``mag`` (any unit, or None: ``update_no_magnetometer``) are
    ``(T, 3)``; ``out`` is ``(T, 4)`` float64, ``[w, x, y, z]`` as ``Ahrs.get_quaternion`` gives it.
    ``feedback``: None, or paper 001's feedback hybrid as ``(blend_at, q_s, mu)`` ``(T,)``, ``(T, 4)``,
    ``(T,)``: after the update of a sample ``blend_at``, :func:`_blend`.  ``native``: :data:`CHECKED`
    (default: the compiled loop where it applies), None (``Ahrs.update`` from Python) or the triple of
    :func:`_native_calls` to use.
    """

    def __init__(self, ahrs: imufusion.Ahrs, gyr_deg, acc_g, mag, out: np.ndarray, feedback=None, native=CHECKED):
        self._ahrs, self._out, self._with_mag = ahrs, out, mag is not None
        self._native = _native_calls() if native is CHECKED else native
        self._feedback = ((np.zeros(0, dtype=bool), np.zeros((0, 4)), np.zeros(0)) if feedback is None
                          else tuple(np.ascontiguousarray(x) for x in feedback))
        signals = (gyr_deg, acc_g) + ((mag,) if self._with_mag else ())
        if self._native is not None:
            self._state = _struct_floats(ahrs)
            self._address = id(ahrs) + _HEADER_BYTES
            self._signals = tuple(_lanes(x) for x in signals)
        else:
            with paused_collector():  # thousands of new lists would start the cyclic collector over and over
                self._signals = tuple(np.asarray(x).tolist() for x in signals)

    def run(self, start: int, end: int) -> None:
        """Update with samples ``start … end − 1``; ``out[start:end]`` the quaternions after each."""
        if self._native is None:
            self._run_in_python(start, end)
            return
        update_9d, update_6d, q_at = self._native
        if self._with_mag:
            _run_9d(update_9d, self._address, self._state, q_at, *self._signals, self._out, start, end,
                    *self._feedback)
        else:
            _run_6d(update_6d, self._address, self._state, q_at, *self._signals, self._out, start, end,
                    *self._feedback)

    def _run_in_python(self, start: int, end: int) -> None:
        out, quaternion = self._out, self._ahrs.get_quaternion
        update = self._ahrs.update if self._with_mag else self._ahrs.update_no_magnetometer
        rows = self._signals
        blend_at, q_s, mu = self._feedback
        scratch = np.empty(4, dtype=np.float32)  # _blend's write to the struct, which set_quaternion makes here
        for t in range(start, end):
            update(*(row[t] for row in rows))
            out[t] = quaternion()
            if blend_at.size and blend_at[t]:
                _blend(scratch, 0, out, t, q_s[t], mu[t])
                self._ahrs.set_quaternion(out[t])


@functools.cache
def _native_calls():
    """``(update_9d, update_6d, q_at)``: the C functions and the quaternion's float offset in the
    struct, or None where the compiled loop does not apply or does not reproduce ``Ahrs.update``."""
    if (platform.machine().lower() not in ("x86_64", "amd64") or sys.platform == "win32"
            or sys.implementation.name != "cpython"):  # CPython: id() is the object's address
        return None
    version = importlib.metadata.version("imufusion")
    if not version.startswith(CHECKED_VERSIONS):
        warn_user(f"imufusion {version}: its C update is called only for versions {CHECKED_VERSIONS[0]}x (their "
                  "argument layout is the one described here); Fusion runs from Python (slower)")
        return None
    try:
        library = ctypes.CDLL(imufusion.__file__)
        calls = (_UPDATE_9D(("FusionAhrsUpdate", library)), _UPDATE_6D(("FusionAhrsUpdateNoMagnetometer", library)))
    except (OSError, AttributeError) as exc:  # not loadable again, or the symbols are not exported
        warn_user(f"imufusion's C update is not reachable ({exc}): Fusion runs from Python (slower)")
        return None
    probe = imufusion.Ahrs()
    marker = np.array([0.5, -0.1, 0.7, 0.5])
    probe.set_quaternion(marker / np.linalg.norm(marker))
    found = np.flatnonzero(np.all(np.lib.stride_tricks.sliding_window_view(_struct_floats(probe), 4)
                                  == np.float32(probe.get_quaternion()), axis=-1))
    if found.size != 1:
        warn_user("imufusion's struct layout is not the expected one: Fusion runs from Python (slower)")
        return None
    native = (*calls, int(found[0]))
    if not all(_agrees(native, with_mag) for with_mag in (True, False)):
        warn_user("imufusion's C update did not reproduce Ahrs.update: Fusion runs from Python (slower)")
        return None
    return native


def _agrees(native, with_mag: bool) -> bool:
    """The compiled loop and ``Ahrs.update`` give the same bits on a short recording that starts the
    ramp, rejects, recovers, has zero components and vectors, is set mid-way and blended (feedback)."""
    n_t = 400
    t = np.arange(n_t)[:, None] * np.array([0.031, 0.017, 0.023])
    gyr = 90.0 * np.sin(t * [1.0, 2.0, 3.0])
    gyr[::7, 1] = 0.0
    acc = np.cos(t) * [0.3, 0.0, 0.2] + [0.0, 0.0, 1.0]
    acc[150:170] = 0.0
    mag = np.cos(2 * t) * [5.0, 3.0, 0.0] + [0.0, 20.0, -40.0]
    mag[200:210] = 0.0
    settings = imufusion.AhrsSettings()
    settings.sample_rate, settings.gain, settings.gyroscope_range = 50.0, 0.5, 250.0
    settings.acceleration_rejection, settings.magnetic_rejection, settings.rejection_timeout = 5.0, 5.0, 0.5
    blend_at = np.zeros(n_t, dtype=bool)
    blend_at[250::7] = True
    q_s = np.tile([0.5, 0.5, -0.5, 0.5], (n_t, 1))
    feedback = (blend_at, q_s, np.linspace(0.0, 1.0, n_t))
    outs = []
    for calls in (None, native):
        ahrs = imufusion.Ahrs()
        ahrs.set_settings(settings)
        out = np.empty((n_t, 4))
        updates = FusionUpdates(ahrs, gyr, acc, mag if with_mag else None, out, feedback, native=calls)
        updates.run(0, n_t // 2)
        ahrs.set_quaternion(np.array([0.0, 0.6, 0.0, 0.8]))
        updates.run(n_t // 2, n_t)
        outs.append(out)
    return np.array_equal(outs[0], outs[1])
