"""Argument checks and the batch driver shared by the orientation filters.

Every check raises a ``ValueError`` that names the argument.  :func:`run_filter` turns the
broadcast of the inputs into index arrays for the compiled kernels of :mod:`._kernels` (no
broadcast copies of the signals), after checking that the output fits in memory, and runs
:func:`._kernels.run_filter`; :func:`wsnlib.orientation.madgwick` and
:func:`wsnlib.orientation.estimate_orientation` are both this call.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numba import get_num_threads

from wsnlib._user_warnings import warn_user
from wsnlib._validation import as_float_array, check_choice, real_array
from wsnlib.orientation import _kernels as K
from wsnlib.orientation import gaps
from wsnlib.plausibility import SAMPLE_NORM_MAX, check_imu_plausible, implausible_samples

#: Largest sampling rate (Hz) and smallest one accepted: outside, Δt·|ω| or β·Δt overflow.
FS_RANGE = (1e-6, 1e9)
#: Largest gain β (rad/s) accepted (a step of β·Δt per sample; useful values are below 10).
BETA_LIMIT = 1e6
#: Above this many samples the received-sample check runs in parallel.
PARALLEL_CHECK_SAMPLES = 2**22
#: Share of the memory available now that one call may take for its output.
MEMORY_SHARE = 0.8


def positive_array(value, name: str, allow_inf: bool = False) -> np.ndarray:
    """``value`` as a float array > 0 (and finite, unless ``allow_inf``), else ``ValueError`` naming it."""
    if allow_inf:
        arr = np.asarray(value, dtype=float)
        if np.any(np.isnan(arr)) or np.any(arr <= 0.0):
            raise ValueError(f"{name} must be > 0 (inf allowed), got {value!r}")
        return arr
    arr = as_float_array(value, name, min_ndim=0)  # raises on NaN/inf, naming the argument
    if np.any(arr <= 0.0):
        raise ValueError(f"{name} must be > 0 (and finite), got {value!r}")
    return arr


def nonnegative_array(value, name: str) -> np.ndarray:
    arr = as_float_array(value, name, min_ndim=0)
    if np.any(arr < 0.0):
        raise ValueError(f"{name} must be >= 0 (and finite), got {value!r}")
    return arr


def check_fs(fs) -> float:
    """``fs`` (Hz) as a float in :data:`FS_RANGE`."""
    try:
        value = float(fs)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"fs must be a positive number (Hz), got {fs!r}") from exc
    low, high = FS_RANGE
    if not low <= value <= high:
        raise ValueError(f"fs must lie in [{low:g}, {high:g}] Hz (and be finite), got {fs!r}")
    return value


def check_beta(value, name: str = "beta") -> np.ndarray:
    """Gain(s) β (rad/s) in ``[0, BETA_LIMIT]`` as a float array."""
    beta = nonnegative_array(value, name)
    if np.any(beta > BETA_LIMIT):
        raise ValueError(f"{name} must be <= {BETA_LIMIT:g} rad/s, got {value!r}")
    return beta


def check_received(received, n_t: int | None = None) -> np.ndarray:
    """``received`` as a boolean array ``(..., T)``; given ``n_t``, T must be ``n_t`` and None means
    every sample received (all True, shape ``(n_t,)``)."""
    if received is None and n_t is not None:
        return np.ones(n_t, dtype=bool)
    mask = np.asarray(received)
    if mask.dtype != np.bool_:
        raise ValueError(f"received must be a boolean mask (True = received), got dtype {mask.dtype}")
    if mask.ndim < 1:
        raise ValueError(f"received must have shape (..., T), got shape {mask.shape}")
    if n_t is not None and mask.shape[-1] != n_t:
        raise ValueError(f"received must have shape (..., {n_t}), got {mask.shape}")
    return mask


def check_hold_window(hold_window, schedule: str, default: int) -> np.ndarray | None:
    """``hold_window`` as an int64 array for ``schedule="hold"``, else ``None``."""
    if schedule != "hold":
        if hold_window is not None:
            raise ValueError(f"hold_window is only used with schedule='hold', not schedule={schedule!r}")
        return None
    if hold_window is None:
        return np.asarray(default, dtype=np.int64)
    arr = np.asarray(hold_window)
    if arr.dtype == np.bool_ or not np.issubdtype(arr.dtype, np.integer) or np.any(arr < 1):
        raise ValueError(f"hold_window must be a positive integer (samples) or an array of them, got {hold_window!r}")
    return arr.astype(np.int64)


def broadcast_batch(shapes: dict[str, tuple[int, ...]]) -> tuple[int, ...]:
    try:
        return np.broadcast_shapes(*shapes.values())
    except ValueError as exc:
        listed = ", ".join(f"{name} {shape}" for name, shape in shapes.items())
        raise ValueError(f"leading (batch) dimensions do not broadcast: {listed}") from exc


def as_signal(value, name: str) -> np.ndarray:
    """Float array of shape ``(..., T, 3)``; finiteness is checked later, on received samples."""
    arr = real_array(value, name)
    if arr.ndim < 2 or arr.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (..., T, 3), got shape {arr.shape}")
    return arr


def unbroadcast(value):
    """``value`` with each leading axis that numpy broadcast (stride 0, e.g. ``np.broadcast_to``) cut to
    length 1, so that it is never materialised: the kernels' batch index (:func:`index_into`) repeats
    it.  Anything but an array of ndim ≥ 3 is returned as it is."""
    if not isinstance(value, np.ndarray) or value.ndim < 3:
        return value
    lead = value.ndim - 2
    return value[tuple(slice(0, 1) if value.strides[i] == 0 else slice(None) for i in range(lead))]


def nonzero_vectors(value, name: str, last_dim: int, what: str) -> np.ndarray:
    """Finite float array ``(..., last_dim)`` without a zero vector (``what`` says why it needs one)."""
    arr = as_float_array(value, name, last_dim=last_dim)
    scale = np.max(np.abs(arr), axis=-1, keepdims=True)
    if np.any(scale == 0.0):
        bad = tuple(int(i) for i in np.argwhere(scale[..., 0] == 0.0)[0])
        raise ValueError(f"{name} has a zero-norm vector at index {bad} ({what})")
    return arr


def unit_quaternions(value, name: str) -> np.ndarray:
    """Finite, non-zero quaternions ``(..., 4)`` scaled to unit norm (huge or tiny ones too)."""
    q = nonzero_vectors(value, name, 4, "a zero quaternion is not a rotation")
    q = q / np.max(np.abs(q), axis=-1, keepdims=True)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def check_inputs(gyr, acc, mag, received, q0=None):
    """Shared argument checks of the whole-recording filters (madgwick, loss handling, peers).

    Returns the signals ``{"gyr", "acc"[, "mag"]}`` as float arrays ``(..., T, 3)`` (finiteness
    is checked later, on received samples only: :func:`check_usable`; leading axes the caller
    broadcast are length 1 here, :func:`unbroadcast`), ``received`` as a boolean array (all True,
    shape ``(T,)``, where it is None), ``q0`` normalised or None, and the leading (batch) shape of
    each argument as given, by name.
    """
    given = {"gyr": gyr, "acc": acc} | ({} if mag is None else {"mag": mag})
    signals = {name: as_signal(unbroadcast(value), name) for name, value in given.items()}
    n_t = signals["gyr"].shape[-2]
    for name, arr in signals.items():
        if arr.shape[-2] != n_t:
            raise ValueError(f"{name} has {arr.shape[-2]} samples (axis -2), gyr has {n_t}")
    shapes = {name: np.shape(given[name])[:-2] for name in signals}  # the batch the caller asked for
    received = check_received(received, n_t)
    shapes["received"] = received.shape[:-1]
    if q0 is not None:
        q0 = unit_quaternions(q0, "q0")
        shapes["q0"] = q0.shape[:-1]
    return signals, received, q0, shapes


# ------------------------------------------------------------------------------------------
# The loss vocabulary shared by every filter (documented in wsnlib.orientation)
# ------------------------------------------------------------------------------------------

#: ``gap``: what the filter's state does inside a gap.
GAPS = ("hold", "constant_rate", "ar")
#: ``output_on_lost``: what is output on a lost sample.
OUTPUTS_ON_LOST = ("estimate", "hold")
#: ``blend``: where paper 001's SLERP towards the single frame acts (``None``: no hybrid).
BLENDS = ("output", "feedback")


def check_gap(gap, gap_time_constant, filter_name: str, supported=GAPS[:2]) -> tuple[str, float | None]:
    """``gap`` one of ``supported``; ``gap_time_constant`` (s, > 0, ``inf`` = constant) or None,
    not with ``"hold"`` (the state does not turn there)."""
    if not isinstance(gap, str) or gap not in GAPS:
        raise ValueError(f"gap must be one of {', '.join(map(repr, GAPS))}; got {gap!r}")
    if gap not in supported:
        raise ValueError(f"gap={gap!r} is not available for {filter_name} (it supports "
                         f"{', '.join(map(repr, supported))})")
    if gap_time_constant is not None:
        if gap == "hold":
            raise ValueError("gap_time_constant is only used when the state turns in a gap, not with gap='hold'")
        gap_time_constant = float(positive_array(gap_time_constant, "gap_time_constant", allow_inf=True))
    return gap, gap_time_constant


def rate_factor(gap_time_constant, fs: float) -> float:
    """Factor by which a predicted rate decays per lost sample, ``exp(−Δt/τ)`` (1: constant)."""
    if gap_time_constant is None or np.isinf(gap_time_constant):
        return 1.0
    return float(np.exp(-1.0 / (fs * gap_time_constant)))


def check_output_on_lost(output_on_lost) -> bool:
    """``output_on_lost`` one of :data:`OUTPUTS_ON_LOST`; True when the output is held there."""
    return check_choice(output_on_lost, "output_on_lost", OUTPUTS_ON_LOST) == "hold"


def check_blend(blend, mag, filter_name: str) -> str | None:
    """``blend`` None or one of :data:`BLENDS`; the hybrid's TRIAD needs ``mag``."""
    if blend is None:
        return None
    blend = check_choice(blend, "blend", BLENDS)
    if mag is None:
        raise ValueError(f"mag is required for blend={blend!r} in {filter_name}: TRIAD (q_s) needs the magnetometer")
    return blend


def refuse_unused(filter_name: str, why: str, **given) -> None:
    """Raise if any keyword in ``given`` is not None: the call would silently ignore it."""
    passed = [name for name, value in given.items() if value is not None and value is not False]
    if passed:
        raise ValueError(f"{', '.join(passed)} {'is' if len(passed) == 1 else 'are'} not used by {filter_name} "
                         f"{why}; leave {'it' if len(passed) == 1 else 'them'} out")


def hold_lost_output(quat: np.ndarray, received) -> np.ndarray:
    """``output_on_lost="hold"`` for any filter: on every lost sample after the first, in place,
    the output of the sample before (``quat`` ``(*batch, T, C)``, ``received`` broadcasting
    to ``(*batch, T)``)."""
    n_t = quat.shape[-2]
    if n_t and received is not None:
        batch = quat.shape[:-2]
        mask = np.asarray(received)
        K.run_hold_lost(quat.reshape(-1, n_t, quat.shape[-1]), flat(mask, 1), index_into(mask.shape[:-1], batch))
    return quat


def check_has_sample(mask: np.ndarray, batch: tuple[int, ...]) -> None:
    """Every batch element must receive something (when the filter starts from its first sample)."""
    has_sample = np.broadcast_to(mask.any(axis=-1), batch)
    if not np.all(has_sample):
        bad = tuple(int(i) for i in np.argwhere(~has_sample)[0])
        raise ValueError(
            f"received has no received sample for batch element {bad}; pass q0 to define the estimate there"
        )


# ------------------------------------------------------------------------------------------
# From broadcast shapes to the kernels' flat batches
# ------------------------------------------------------------------------------------------


def kernel_input(arr) -> np.ndarray:
    """``arr`` as a C-contiguous, read-only view (a copy only when it is not C-contiguous).

    numba compiles one machine code per argument type, and a read-only array (a cached BROAD
    trial, a broadcast) is another type than a writable one: every input handed to a kernel goes
    through here, so that each kernel is compiled once, whatever the caller's arrays.
    """
    view = np.ascontiguousarray(arr).view()
    view.flags.writeable = False
    return view


def flat(arr: np.ndarray, n_core: int) -> np.ndarray:
    """``arr`` ``(*s, *core)`` as C-contiguous, read-only ``(prod(s), *core)`` (a view when it can be)."""
    core = arr.shape[arr.ndim - n_core :]
    return kernel_input(arr).reshape((int(np.prod(arr.shape[: arr.ndim - n_core], dtype=np.int64)),) + core)


def index_into(shape: tuple[int, ...], batch: tuple[int, ...]) -> np.ndarray:
    """For each element of ``batch`` (C order), the flat index of the element of ``shape`` it reads."""
    size = int(np.prod(shape, dtype=np.int64))
    index = np.arange(size, dtype=np.int64).reshape(shape)
    return kernel_input(np.broadcast_to(index, batch).reshape(-1))


def per_element(value, batch: tuple[int, ...], dtype=float) -> np.ndarray:
    """A scalar or array parameter broadcast to ``batch`` and flattened, ``(prod(batch),)``, read-only."""
    return kernel_input(np.broadcast_to(np.asarray(value, dtype=dtype), batch).reshape(-1))


def available_memory() -> int | None:
    """Bytes of memory available now (Linux ``MemAvailable``), or None where unknown."""
    try:
        with open("/proc/meminfo") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(n_bytes: int, what: str) -> None:
    """Raise ``MemoryError`` at once, with the size, if ``n_bytes`` would not fit."""
    available = available_memory()
    if available is not None and n_bytes > MEMORY_SHARE * available:
        raise MemoryError(
            f"{what} needs {n_bytes / 2**30:.1f} GiB but only {available / 2**30:.1f} GiB of memory is "
            "available: split the batch (e.g. loop over its first dimension)"
        )


def thread_slots(n_items: int) -> int:
    """How many threads :func:`in_threads` runs ``n_items`` on: numba's (``NUMBA_NUM_THREADS``, or what
    ``numba.set_num_threads`` or a joblib worker set), at most one per item."""
    return max(1, min(get_num_threads(), n_items))


def in_threads(run_one, n_items: int) -> None:
    """``run_one(item, slot)`` for every ``item`` in ``range(n_items)``, on :func:`thread_slots` threads:
    thread ``slot`` runs a contiguous block of the items, in order (``slot`` picks its scratch).

    For a batch of streams whose compiled loop releases the GIL (``nogil=True``): the threads run it
    side by side, as a ``prange`` driver would, without a compiled driver of their own (numba compiles
    a ``prange`` loop around a large kernel as a second copy of it: seconds of compile time, once per
    cache).  One item, or one thread: in this thread.
    """
    n_slots = thread_slots(n_items)
    if n_slots == 1:
        for item in range(n_items):
            run_one(item, 0)
        return
    bounds = np.linspace(0, n_items, n_slots + 1).round().astype(int)

    def run_block(slot):
        for item in range(bounds[slot], bounds[slot + 1]):
            run_one(item, slot)

    with ThreadPoolExecutor(max_workers=n_slots) as pool:
        for done in [pool.submit(run_block, slot) for slot in range(n_slots)]:
            done.result()  # (re-raises a thread's exception here)


def new_output(batch: tuple[int, ...], n_t: int, n_components: int = 4) -> np.ndarray:
    """An uninitialised ``(*batch, T, C)`` float array, after :func:`check_memory`."""
    n_bytes = 8 * n_components * n_t * int(np.prod(batch, dtype=np.int64))
    check_memory(n_bytes, f"an output of shape {batch + (n_t, n_components)}")
    return np.empty(batch + (n_t, n_components))


def check_usable(signals: dict[str, np.ndarray], received: np.ndarray, gravity: float | None = None) -> np.ndarray:
    """Raise if a received sample is not finite (or, for ``acc``/``mag``, a zero vector), or if
    the recording is implausible as a whole (:func:`wsnlib.plausibility.check_imu_plausible`:
    gyro in deg/s, acc and mag swapped, and, given the filter's ``gravity``, acc in g); return the
    mask the filter uses: ``received`` less the received samples whose norm no sensor can read
    (:func:`wsnlib.plausibility.implausible_samples`), treated as lost with one ``UserWarning``.

    Reported at the first such sample in (batch..., t) order of the broadcast of the signal
    and the mask, ``gyr`` then ``acc`` then ``mag``.  Lost samples are never checked.
    """
    for name, arr in signals.items():
        n_t = arr.shape[-2]
        batch = np.broadcast_shapes(arr.shape[:-2], received.shape[:-1])
        result = np.empty((int(np.prod(batch, dtype=np.int64)), 2), dtype=np.int64)
        check = K.first_unusable_parallel if result.shape[0] * n_t > PARALLEL_CHECK_SAMPLES else K.first_unusable
        check(flat(arr, 2), index_into(arr.shape[:-2], batch), flat(received, 1),
              index_into(received.shape[:-1], batch), name != "gyr", result)
        bad = np.flatnonzero(result[:, 0] >= 0)
        if bad.size:
            b = int(bad[0])
            index = np.unravel_index(b, batch) + (int(result[b, 0]),)
            what = "is not finite" if result[b, 1] == 1 else "is a zero vector"
            raise ValueError(f"{name} {what} at received sample (batch..., t) = {tuple(int(i) for i in index)}")
    # the whole recording first (a unit mistake makes every sample implausible), then single samples
    check_imu_plausible(signals.get("gyr"), signals["acc"], signals.get("mag"), received, gravity=gravity)
    implausible = implausible_samples(signals)
    if implausible is not None and (implausible & received).any():
        n_lost = int((implausible & received).sum())
        limits = ", ".join(f"|{name}| > {SAMPLE_NORM_MAX[name]:g}" for name in signals)
        warn_user(f"{n_lost} received sample(s) with an implausible reading ({limits}; rad/s, m/s², µT) "
                  f"are treated as lost")
        received = received & ~implausible
    return received


def raise_on_status(status: np.ndarray, batch: tuple[int, ...], **params) -> None:
    """Turn a kernel's status into a ``ValueError``: PARALLEL names the batch element, OVERFLOW also the parameters."""
    bad = np.flatnonzero(status != K.OK)
    if bad.size:
        index = tuple(int(i) for i in np.unravel_index(int(bad[0]), batch))
        if status[bad[0]] == K.PARALLEL:
            raise ValueError(f"acc and mag are parallel on a received sample of batch element {index} where TRIAD is "
                             f"needed (the start without q0, or the hybrid's single frame after a gap): the heading "
                             f"is undefined there")
        listed = ", ".join(f"{k}={v!r}" for k, v in params.items())
        raise ValueError(
            f"the filter overflowed (a non-finite estimate) in batch element {index}: the parameters are "
            f"too extreme for the data ({listed}); Δt·|ω| and β·Δt must stay far below 1e150"
        )


def run_filter(signals, received, q0, batch, *, fs, method=K.STANDARD, replay=False, blend=K.NO_BLEND, beta=0.0,
               beta_max=None, rho=1.0, tau=1.0, schedule=K.DECAY, window=1, gap="hold", gap_time_constant=None,
               ar_order=1, ar_window=0, single_frame_gate=None) -> np.ndarray:
    """Madgwick's filter with a loss-handling method over a batch: ``(*batch, T, 4)``.

    ``signals`` from :func:`check_inputs` (checked here with :func:`check_usable`), ``received``
    ``(..., T)`` bool, ``q0`` ``(..., 4)`` unit or None (then every batch element must
    receive a sample), ``batch`` the broadcast of all leading shapes, parameters (scalars or
    arrays broadcasting to ``batch``) as in :func:`._kernels.filter_stream`; ``gap`` and
    ``gap_time_constant`` checked by :func:`check_gap`, ``ar_order`` and ``ar_window`` (samples)
    the AR predictor's with ``gap="ar"``;
    ``single_frame_gate`` the gated hybrid's vector (:data:`._kernels.GATE_SIZE` floats, needs
    ``mag``) or None.
    """
    n_t = signals["gyr"].shape[-2]
    out = new_output(batch, n_t)
    if n_t == 0:
        return out
    mask = check_usable(signals, received)
    if q0 is None:
        check_has_sample(mask, batch)
    use_mag = "mag" in signals
    gyr, acc = flat(signals["gyr"], 2), flat(signals["acc"], 2)
    mag = flat(signals["mag"] if use_mag else np.zeros((1, 1, 3)), 2)
    masks = flat(mask, 1)
    starts = flat(np.array([[1.0, 0.0, 0.0, 0.0]]) if q0 is None else q0, 1)
    beta_max = beta if beta_max is None else beta_max
    params = [per_element(x, batch) for x in (beta, beta_max, rho, tau)]
    windows = per_element(window, batch, np.int64)
    gap_settings = gaps.new_gap_state(gaps.GAP_CODES[gap], rate_factor(gap_time_constant, fs), ar_order, ar_window)
    # The rate history: the AR fit's window and the longest gap replayed with its predicted rates.
    history_rows = gaps.history_length(ar_window, int(np.ceil(gaps.LONGEST_AR_REPLAY_S * fs))) if gap == "ar" else 2
    gated = single_frame_gate is not None
    gate = kernel_input(np.zeros(K.GATE_SIZE) if single_frame_gate is None
                        else np.asarray(single_frame_gate, dtype=float))
    flat_out = out.reshape(-1, n_t, 4)
    status = np.empty(flat_out.shape[0], dtype=np.int64)
    if status.size == 1:  # one stream: the loop itself, no thread start-up
        status[0] = K.filter_stream(gyr[0], acc[0], mag[0], use_mag, masks[0], starts[0], q0 is not None,
                                    method, replay, blend, 1.0 / fs, *(x[0] for x in params), schedule, windows[0],
                                    gap_settings, history_rows, gated, gate, flat_out[0])
    else:
        index = [index_into(shape, batch) for shape in (signals["gyr"].shape[:-2], signals["acc"].shape[:-2],
                                                        signals["mag"].shape[:-2] if use_mag else (),
                                                        mask.shape[:-1], () if q0 is None else q0.shape[:-1])]
        K.run_filter(gyr, acc, mag, use_mag, masks, starts, q0 is not None, *index, method, replay, blend, 1.0 / fs,
                     *params, schedule, windows, gap_settings, history_rows, gated, gate, flat_out, status)
    raise_on_status(status, batch, fs=fs, beta=beta)
    return out
