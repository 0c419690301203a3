"""VQF's updates over a run of samples: vqf's own C++ member functions, called from a compiled loop.

From Python, ``vqf.VQF``'s calls cost far more than the C++ they run: ``updateBatch`` checks its
arguments and returns a dict of seven new arrays (~15 µs a call, whatever the run's length), ``update``
and ``updateGyr`` ~2 µs a sample around ~0.5 µs of C++, and the ``state`` property builds or reads a
dict of new lists (~4 µs to read, ~3 µs to write).  The peers' gap handling calls them once per run
of received samples, per lost sample (``gap="ar"``) and per blended sample (the feedback hybrid).

``vqf.VQF`` (2.1.x) is a Cython class whose object holds a pointer to its C++ ``VQF`` right after the
Python object header (``cdef C_VQF* c_obj``, the package's ``vqf.pyx``), and its extension module
exports the C++ member functions (Itanium C++ ABI names; ``this`` is the first argument, arrays are
pointers): ``VQF::update`` (with and without magnetometer), ``VQF::updateGyr``, ``VQF::getQuat6D`` and
``VQF::getQuat9D``, and ``VQF::getState``, the address of the object's ``VQFState``, whose first nine
doubles are ``gyrQuat``, ``accQuat`` and ``delta`` (``vqf.hpp``).  So :class:`VQFUpdates` calls those
very functions on that very object from numba loops, and reads and writes those nine doubles in
place: the same machine code on the same state, hence bit for bit what ``updateBatch``, ``update``,
``updateGyr`` and the ``state`` property give (``updateBatch`` is ``update`` then ``getQuat6D``/
``getQuat9D`` per sample), and the Python methods (``state``, for the replay's snapshot) still act on
the state the loops update.

Checked, not trusted: before first use the compiled loops and vqf's Python methods run the same
short recording (runs cut anywhere, rest and motion, a gap's ``updateGyr`` rates, the output set
mid-way, the feedback hybrid's blends) and must agree bit for bit, outputs and final state.
Elsewhere than CPython on x86-64 System V every call goes through vqf's Python methods (the same
results, slower), and so, with a warning, with a vqf other than :data:`CHECKED_VERSIONS`, without the
exported functions, or when the two do not agree.  ``tests/test_peers.py`` checks both paths against
each other.
"""

from __future__ import annotations

import ctypes
import functools
import importlib
import importlib.metadata
import math
import platform
import sys

import numpy as np
import vqf
from numba import njit

from wsnlib._user_warnings import warn_user
from wsnlib.orientation._scalar_kernels import (
    COMPILE,
    PLAIN_TRUE,
    quat_conjugate,
    quat_multiply,
    quat_normalize,
    slerp,
)

#: vqf versions whose object layout and exported functions are the ones described here (checked on
#: each at first use).
CHECKED_VERSIONS = ("2.1.",)
#: Bytes of the Python object header (``PyObject_HEAD``) that the pointer to the C++ object follows.
_HEADER_BYTES = object.__basicsize__
#: ``gyrQuat`` (4), ``accQuat`` (4), ``delta``: the first doubles of ``VQFState``.
_GYR_QUAT, _ACC_QUAT, _DELTA, _STATE_DOUBLES = 0, 4, 8, 9

# Every argument is an address (``this`` or an array's data) as a pointer-sized integer, which travels
# in the same register as a pointer.
_ADDRESS = ctypes.c_size_t
_SYMBOLS = {  # name: (Itanium ABI symbol, ctypes prototype)
    "update_9d": ("_ZN3VQF6updateEPKdS1_S1_", ctypes.CFUNCTYPE(None, _ADDRESS, _ADDRESS, _ADDRESS, _ADDRESS)),
    "update_6d": ("_ZN3VQF6updateEPKdS1_", ctypes.CFUNCTYPE(None, _ADDRESS, _ADDRESS, _ADDRESS)),
    "update_gyr": ("_ZN3VQF9updateGyrEPKd", ctypes.CFUNCTYPE(None, _ADDRESS, _ADDRESS)),
    "quat_9d": ("_ZNK3VQF9getQuat9DEPd", ctypes.CFUNCTYPE(None, _ADDRESS, _ADDRESS)),
    "quat_6d": ("_ZNK3VQF9getQuat6DEPd", ctypes.CFUNCTYPE(None, _ADDRESS, _ADDRESS)),
    "state": ("_ZNK3VQF8getStateEv", ctypes.CFUNCTYPE(_ADDRESS, _ADDRESS)),
}


@njit(**COMPILE)
def gyr_quat_for_output(q_f, acc_quat, delta, use_mag):
    """``gyrQuat = accQuat* ⊗ q_z(−δ) ⊗ q_f`` (normalised; 4-tuples): VQF's 9D output ``q_z(δ) ⊗ accQuat ⊗
    gyrQuat`` is then ``q_f`` (its 6D output without ``use_mag``: δ taken as 0).  Why ``gyrQuat`` and not
    ``accQuat``: :mod:`wsnlib.orientation.peers`."""
    half = -0.5 * delta if use_mag else 0.0
    undo_delta = (math.cos(half), 0.0, 0.0, math.sin(half))
    return quat_normalize(quat_multiply(quat_conjugate(acc_quat), quat_multiply(undo_delta, q_f)))


@njit(inline="always", **COMPILE)
def _state_quat(state, at):
    return state[at], state[at + 1], state[at + 2], state[at + 3]


@njit(**COMPILE)
def _set_output(state, q_f, use_mag):
    """Make the state's 9D output (6D without ``use_mag``) ``q_f`` (4,) by replacing ``gyrQuat``."""
    q = gyr_quat_for_output((q_f[0], q_f[1], q_f[2], q_f[3]), _state_quat(state, _ACC_QUAT), state[_DELTA], use_mag)
    for i in range(4):
        state[_GYR_QUAT + i] = q[i]


@njit(**COMPILE)
def _blend(state, out, t, q_s, mu):
    """Paper 001's feedback hybrid on sample ``t``: ``out[t] ← SLERP(q_s, out[t], μ)`` (eq. (4),
    :func:`~wsnlib.orientation._scalar_kernels.slerp`), and the filter continues from it (the 9D output
    made ``out[t]``, :func:`_set_output`)."""
    q = slerp((q_s[0], q_s[1], q_s[2], q_s[3]), (out[t, 0], out[t, 1], out[t, 2], out[t, 3]), mu)
    for i in range(4):
        out[t, i] = q[i]
    _set_output(state, out[t], PLAIN_TRUE)


@njit(inline="always", **COMPILE)
def _row(x, t):
    """The address of row ``t`` of the C-ordered ``x``."""
    return x.ctypes.data + t * x.strides[0]


@njit(**COMPILE)
def _run_9d(update, get_quat, this, state, gyr, acc, mag, out, start, end, blend_at, q_s, mu):
    """``update(this, gyr, acc, mag)`` for samples ``start … end − 1``, ``get_quat`` after each into
    ``out[t]``; on samples ``blend_at`` (``(T,)`` bool, or ``(0,)``: none) the feedback hybrid
    :func:`_blend` with ``q_s[t]``, ``mu[t]``."""
    for t in range(start, end):
        update(this, _row(gyr, t), _row(acc, t), _row(mag, t))
        get_quat(this, _row(out, t))
        if blend_at.size and blend_at[t]:
            _blend(state, out, t, q_s[t], mu[t])


@njit(**COMPILE)
def _run_6d(update, get_quat, this, gyr, acc, out, start, end):
    """:func:`_run_9d` without magnetometer (the feedback hybrid needs one)."""
    for t in range(start, end):
        update(this, _row(gyr, t), _row(acc, t))
        get_quat(this, _row(out, t))


@njit(**COMPILE)
def _turn(update_gyr, get_quat, this, rates, out):
    """``updateGyr`` with each row of ``rates`` (L, 3), ``get_quat`` after each into that row of ``out``
    (L, 4), or nowhere when ``out`` has no rows."""
    for k in range(rates.shape[0]):
        update_gyr(this, _row(rates, k))
        if out.shape[0]:
            get_quat(this, _row(out, k))


_NO_FEEDBACK = (np.zeros(0, dtype=bool), np.zeros((0, 4)), np.zeros(0))

#: :class:`VQFUpdates`' default ``native``: the checked C++ functions where they apply (:func:`_native_calls`).
CHECKED = "checked"


class VQFUpdates:
    """VQF's calls on one recording: :meth:`run` feeds ``filt`` the samples ``start … end − 1`` and writes
    its quaternion after each into ``out``; :meth:`turn` (``updateGyr``) and :meth:`set_output` (its
    ``gyrQuat``) are what the gap handling needs.

    ``gyr`` (rad/s), ``acc`` (m/s²) and ``mag`` (any unit, or None: 6D) are ``(T, 3)``; ``out`` is ``(T, 4)``
    float64, ``quat9D`` (``quat6D`` without ``mag``).  ``feedback``: None, or paper 001's feedback hybrid as
    ``(blend_at, q_s, mu)`` ``(T,)``, ``(T, 4)``, ``(T,)`` (needs ``mag``): after the update of a sample
    ``blend_at``, :func:`_blend`.  ``native``: :data:`CHECKED` (default: the compiled loops where they
    apply), None (vqf's Python methods) or the calls of :func:`_native_calls` to use.
    """

    def __init__(self, filt: vqf.VQF, gyr, acc, mag, out: np.ndarray, feedback=None, native=CHECKED):
        if feedback is not None and mag is None:
            raise ValueError("the feedback hybrid needs mag")
        self._filt, self._out, self._with_mag = filt, out, mag is not None
        self._native = _native_calls() if native is CHECKED else native
        self._feedback = _NO_FEEDBACK if feedback is None else tuple(np.ascontiguousarray(x) for x in feedback)
        self._signals = tuple(np.ascontiguousarray(x, dtype=np.float64) for x in (gyr, acc, mag) if x is not None)
        if self._native is not None:
            self._this = ctypes.c_void_p.from_address(id(filt) + _HEADER_BYTES).value
            self._state = _state_view(self._native["state"](self._this))

    def run(self, start: int, end: int) -> None:
        """Update with samples ``start … end − 1``; ``out[start:end]`` the quaternions after each."""
        if self._native is None:
            self._run_in_python(start, end)
        elif self._with_mag:
            native = self._native
            _run_9d(native["update_9d"], native["quat_9d"], self._this, self._state, *self._signals, self._out, start,
                    end, *self._feedback)
        else:
            _run_6d(self._native["update_6d"], self._native["quat_6d"], self._this, *self._signals, self._out, start,
                    end)

    def turn(self, rates: np.ndarray, out: np.ndarray | None = None) -> None:
        """``updateGyr`` with each row of ``rates`` (L, 3) rad/s, the quaternion after each into that row of
        ``out`` (L, 4) if given (a gap's outputs)."""
        rates = np.ascontiguousarray(rates, dtype=np.float64)
        if self._native is None:
            quat = self._quat_in_python()
            for k, rate in enumerate(rates):
                self._filt.updateGyr(rate)
                if out is not None:
                    out[k] = quat()
            return
        native = self._native
        _turn(native["update_gyr"], native["quat_9d" if self._with_mag else "quat_6d"], self._this, rates,
              np.empty((0, 4)) if out is None else out)

    def set_output(self, q_f) -> None:
        """Make the filter's output (9D, or 6D without ``mag``) the unit quaternion ``q_f`` (4,) by replacing
        ``gyrQuat`` (:func:`gyr_quat_for_output`)."""
        q_f = np.ascontiguousarray(q_f, dtype=np.float64)
        if self._native is not None:
            _set_output(self._state, q_f, self._with_mag)
            return
        state = self._filt.state
        state["gyrQuat"] = gyr_quat_for_output(tuple(q_f.tolist()), tuple(state["accQuat"]), state["delta"],
                                               self._with_mag)
        self._filt.state = state

    def _quat_in_python(self):
        return self._filt.getQuat9D if self._with_mag else self._filt.getQuat6D

    def _run_in_python(self, start: int, end: int) -> None:
        """:meth:`run` through vqf's Python methods: ``updateBatch`` on the runs between blended samples."""
        out, filt = self._out, self._filt
        blend_at, q_s, mu = self._feedback
        key = "quat9D" if self._with_mag else "quat6D"
        cuts = [start] + ([] if not blend_at.size else (np.flatnonzero(blend_at[start:end]) + start + 1).tolist())
        if cuts[-1] != end:
            cuts.append(end)
        for first, stop in zip(cuts[:-1], cuts[1:], strict=True):
            piece = tuple(x[first:stop] for x in self._signals)
            if stop - first == 1:  # one sample: the same update, without a batch's arrays
                filt.update(*(x[0] for x in piece))
                out[first] = self._quat_in_python()()
            else:
                out[first:stop] = filt.updateBatch(*piece)[key]
            last = stop - 1
            if blend_at.size and blend_at[last]:
                scratch = np.zeros(_STATE_DOUBLES)  # _blend's state write, which the state property makes here
                state = filt.state
                scratch[_ACC_QUAT:_ACC_QUAT + 4], scratch[_DELTA] = state["accQuat"], state["delta"]
                _blend(scratch, out, last, q_s[last], mu[last])
                state["gyrQuat"] = scratch[_GYR_QUAT:_GYR_QUAT + 4]
                filt.state = state


def _state_view(address: int) -> np.ndarray:
    """The first :data:`_STATE_DOUBLES` doubles of the ``VQFState`` at ``address`` (a view: valid while its
    ``vqf.VQF`` lives)."""
    return np.frombuffer((ctypes.c_double * _STATE_DOUBLES).from_address(address), dtype=np.float64)


@functools.cache
def _native_calls():
    """The C++ functions (:data:`_SYMBOLS`' names), or None where the compiled loops do not apply or do not
    reproduce vqf's Python methods."""
    if (platform.machine().lower() not in ("x86_64", "amd64") or sys.platform == "win32"
            or sys.implementation.name != "cpython"):  # CPython: id() is the object's address
        return None
    version = importlib.metadata.version("vqf")
    if not version.startswith(CHECKED_VERSIONS) or vqf.VQF.__basicsize__ != _HEADER_BYTES + ctypes.sizeof(
            ctypes.c_void_p):
        warn_user(f"vqf {version}: its C++ functions are called only for versions {CHECKED_VERSIONS[0]}x (their "
                  "object layout is the one described here); VQF runs from Python (slower)")
        return None
    try:
        library = ctypes.CDLL(importlib.import_module("vqf.vqf").__file__)
        native = {name: prototype((symbol, library)) for name, (symbol, prototype) in _SYMBOLS.items()}
    except (OSError, AttributeError, ImportError) as exc:  # not loadable again, or the symbols are not exported
        warn_user(f"vqf's C++ functions are not reachable ({exc}): VQF runs from Python (slower)")
        return None
    if not (_state_found(native) and all(_agrees(native, with_mag) for with_mag in (True, False))):
        warn_user("vqf's C++ functions did not reproduce its Python methods: VQF runs from Python (slower)")
        return None
    return native


def _state_found(native) -> bool:
    """``getState`` of the object's pointer holds ``gyrQuat``, ``accQuat`` and ``delta`` where expected."""
    probe = vqf.VQF(0.02)
    state = probe.state
    state["gyrQuat"], state["accQuat"], state["delta"] = [0.5, -0.1, 0.7, 0.5], [0.3, 0.9, -0.2, 0.1], 0.25
    probe.state = state
    this = ctypes.c_void_p.from_address(id(probe) + _HEADER_BYTES).value
    expected = np.concatenate((state["gyrQuat"], state["accQuat"], [state["delta"]]))
    return this is not None and np.array_equal(_state_view(native["state"](this)), expected)


def _agrees(native, with_mag: bool) -> bool:
    """The compiled loops and vqf's Python methods give the same bits, outputs and final state, on a short
    recording that rests and moves, is cut into runs anywhere, has a gap turned by ``updateGyr``, its output
    set mid-way and (with ``mag``) the feedback hybrid's blends."""
    n_t = 600
    t = np.arange(n_t)[:, None] * np.array([0.031, 0.017, 0.023])
    gyr = 2.0 * np.sin(t * [1.0, 2.0, 3.0])
    gyr[:120] = 0.001  # rest: VQF's rest detection and bias estimation
    acc = np.cos(t) * [0.3, 0.0, 0.2] + [0.0, 0.0, 9.81]
    mag = np.cos(2 * t) * [5.0, 3.0, 0.0] + [0.0, 20.0, -40.0]
    mag[300:340] *= 3.0  # a disturbed field
    blend_at = np.zeros(n_t, dtype=bool)
    blend_at[[250, 251, 252, 259, 399, 599]] = True
    q_s = np.tile([0.5, 0.5, -0.5, 0.5], (n_t, 1))
    feedback = (blend_at, q_s, np.linspace(0.0, 1.0, n_t)) if with_mag else None
    outs, states = [], []
    for calls in (None, native):
        filt = vqf.VQF(0.02)
        out = np.zeros((n_t, 4))
        updates = VQFUpdates(filt, gyr, acc, mag if with_mag else None, out, feedback, native=calls)
        updates.run(0, 1)
        updates.run(1, 250)
        updates.run(250, 253)
        updates.turn(gyr[253:263] * 1.1, out[253:263])  # a gap of ten samples
        updates.turn(gyr[253:263])  # and its replay, without outputs
        updates.run(263, 400)
        updates.set_output([0.0, 0.6, 0.0, 0.8])
        updates.run(400, n_t)
        outs.append(out)
        states.append(repr(filt.state))
    return np.array_equal(outs[0], outs[1]) and states[0] == states[1]
