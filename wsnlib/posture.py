"""Arm posture from radio positions and accelerometer pitch (paper 002, Sections 3.2–3.3).

Giuberti, Martalò, Ferrari, "A hybrid radio/accelerometric approach to arm posture
recognition".  Two steps:

* :func:`pitch_from_acc` — eqs. (5)–(7): the pitch of a body segment is
  ``θ = arcsin(ā_bs)``, the normalised acceleration along the device axis aligned with the
  segment, valid for a still device; during motion, either the paper's gating (keep only
  samples with ``|a| ∈ [g − ξ, g + ξ]``) or a causal low-pass of the acceleration.
* :func:`recursive_chain` — eqs. (8)–(10), repeated segment by segment (footnote 5): the
  heading ψ of a segment is the azimuth of the device's radio position estimate about the
  segment's proximal joint, eq. (8); with the accelerometer pitch θ it gives the corrected
  device position ``D̄``, eq. (9), and the distal joint ``B``, eq. (10), which is the proximal
  joint of the next segment.

d and d′
--------
The paper uses two lengths per segment.  Its Fig. 2 caption, its list of assumptions
("the length d of each body segment …", "the distance d′ between each device and the …
joint proximal to the fixed origin") and eqs. (9)–(10) (``D̄`` at ``d′``, ``B`` at ``d``) all
agree: **d is the segment length (A→B) and d′ the device's distance from the proximal joint
(A→D)**.  One sentence of Section 3.3 ("d is the distance between A and D₁, whereas d′ is the
length of the upper arm") says the opposite; it is outvoted by the caption, the assumptions
and the equations, and would put the elbow at the device.  To avoid the ambiguity the code
never says d or d′: :class:`ArmChain` holds ``segment_lengths_m`` (d) and
``device_offsets_m`` (d′).

Conventions
-----------
* Frame: the paper's Table 1 frame, origin at the shoulder (the fixed point O), **x lateral
  (to the user's right), y forward, z up** (footnote 4).  It is right-handed and is the
  package's ENU frame for a user facing north.
* Heading ψ: azimuth in the x–y plane, ``atan2(Δy, Δx)``, counter-clockwise seen from above,
  reported in ``[0, 2π)`` as in the paper (ψ = 0 points right, π/2 forward).
* Pitch θ: elevation of the segment (proximal → distal) above the horizontal plane, in
  ``[−π/2, π/2]``; positive with the segment pointing above the horizontal, as in eq. (9)
  (``z_D̄ = z_A + d′ sin θ``).  With the package's accelerometer convention (specific force,
  ``+g`` along earth z at rest) a device whose segment axis points up reads ``+g`` along that
  axis, so eq. (7) gives ``θ = +π/2``.
* Units: radians; lengths in metres (any unit works if radio positions, lengths and offsets
  share it); ``acc`` in m/s², ``fs`` in Hz.
"""

from __future__ import annotations

import math

import numpy as np

from wsnlib import fixed_order, frames
from wsnlib._validation import as_float_array, check_count, check_nonnegative, check_nonzero_norm, check_positive
from wsnlib.arm_model import ArmGeometry
from wsnlib.loss import last_received_index
from wsnlib.metrics import SEGMENT_AXIS

#: Default gate half-width ξ (m/s²) of :func:`pitch_from_acc`.  The paper gives no value
#: ("ξ needs to be properly chosen with respect to the application context", ξ ≅ 0 for a
#: still user); 0.5 m/s² (≈ 0.05 g) is our choice: some 40× the white noise of a MEMS
#: accelerometer at rest (≈ 0.01 m/s² RMS for 220 µg/√Hz over 25 Hz), well below the linear
#: accelerations of brisk arm movements (several m/s²).
DEFAULT_XI_M_S2 = 0.5

#: Default cut-off (Hz) of the ``"lowpass"`` method: above the content of the paper's 2–4 s
#: arm movements, below tremor and vibration.  Our choice; the paper only says "a low-pass
#: filter".
DEFAULT_CUTOFF_HZ = 1.0

#: Heading is undefined when the radio estimate's horizontal distance from the proximal
#: joint is at most this (m): "exactly above or below" up to rounding.
DEFAULT_HEADING_TOL_M = 1e-9

PITCH_METHODS = ("gating", "lowpass", "none")


# --- eqs. (5)–(7): pitch from the accelerometer ----------------------------------------------


def gravity_gate(acc, *, xi: float = DEFAULT_XI_M_S2, gravity: float = frames.STANDARD_GRAVITY) -> np.ndarray:
    """Samples whose acceleration magnitude is within ``[g − ξ, g + ξ]`` (Section 3.2).

    Parameters
    ----------
    acc : array_like, shape (..., T, 3)
        Accelerometer readings (m/s², specific force).
    xi : float
        Gate half-width ξ (m/s²), ``>= 0``; default :data:`DEFAULT_XI_M_S2`.
    gravity : float
        g (m/s²); the paper uses 9.81, the package standard gravity 9.80665.

    Returns
    -------
    numpy.ndarray of bool, shape (..., T)
    """
    acc = as_float_array(acc, "acc", last_dim=3, min_ndim=2)
    xi = check_nonnegative(xi, "xi")
    gravity = check_positive(gravity, "gravity")
    return np.abs(np.linalg.norm(acc, axis=-1) - gravity) <= xi


def pitch_from_acc(acc, *, method: str = "gating", xi: float = DEFAULT_XI_M_S2,
                   gravity: float = frames.STANDARD_GRAVITY, fs: float | None = None,
                   cutoff_hz: float = DEFAULT_CUTOFF_HZ, order: int = 2, segment_axis=SEGMENT_AXIS) -> np.ndarray:
    """Segment pitch θ (rad) from accelerometer readings, eqs. (6)–(7), ``(..., T, 3) → (..., T)``.

    ``θ = arcsin(a · u / |a|)`` with ``u`` the device axis along the segment (pointing
    distally).  Positive when the segment points above the horizontal; in ``[−π/2, π/2]``.

    Parameters
    ----------
    acc : array_like, shape (..., T, 3)
        Accelerometer readings in the device frame (m/s², specific force: ``+g`` up at rest).
        Must be finite and never the zero vector.
    method : {"gating", "lowpass", "none"}
        How dynamic acceleration is handled:

        * ``"gating"`` (the paper's): a sample counts only if ``|a| ∈ [g − ξ, g + ξ]``
          (:func:`gravity_gate`).  A rejected sample holds the pitch of the last accepted
          one; rejected samples *before* the first accepted one take the first accepted
          pitch (the only non-causal step).  If no sample of a sequence passes, ``ValueError``.
        * ``"lowpass"``: a causal Butterworth low-pass (``order``, ``cutoff_hz``, at ``fs``)
          on each acceleration axis, run as cascaded second-order sections (numerically
          stable at high orders and low cut-offs, unlike the ``(b, a)`` polynomial form),
          started in its steady state for the first sample (no start-up transient), then
          eq. (6) on the filtered vector.
        * ``"none"``: eq. (6) on every sample as it is.
    xi : float
        Gate half-width ξ (m/s²) for ``"gating"``; default :data:`DEFAULT_XI_M_S2` (ours; the
        paper gives none).
    gravity : float
        g (m/s²) for ``"gating"``.
    fs : float, optional
        Sampling rate (Hz); required for ``"lowpass"``.
    cutoff_hz : float
        Low-pass cut-off (Hz), ``0 < cutoff_hz < fs / 2``; default :data:`DEFAULT_CUTOFF_HZ`.
    order : int
        Butterworth order (``>= 1``).
    segment_axis : array_like, shape (3,)
        Device-frame axis along the segment, pointing distally; normalised here.  Default
        body x, as in eq. (5) and :data:`wsnlib.metrics.SEGMENT_AXIS`.

    Returns
    -------
    numpy.ndarray, shape (..., T)
        Pitch (rad).

    Raises
    ------
    ValueError
        On NaN/inf, zero acceleration vectors, a shape other than ``(..., T, 3)``, an unknown
        method, ``xi < 0``, ``fs <= 0`` or missing for ``"lowpass"``, a cut-off outside
        ``(0, fs/2)``, or when gating rejects every sample of a sequence (the message gives
        the batch index and the gate).
    """
    acc = as_float_array(acc, "acc", last_dim=3, min_ndim=2)
    if method not in PITCH_METHODS:
        raise ValueError(f"method must be one of {PITCH_METHODS}, got {method!r}")
    axis = as_float_array(segment_axis, "segment_axis", last_dim=3)
    if axis.shape != (3,):
        raise ValueError(f"segment_axis must have shape (3,), got {axis.shape}")
    axis = axis / check_nonzero_norm(axis, "segment_axis", "it gives no direction")
    check_nonzero_norm(acc, "acc", "a zero acceleration has no direction")

    if method == "lowpass":
        acc = _lowpass(acc, fs, cutoff_hz, order)
        check_nonzero_norm(acc, "acc", "the low-pass output is zero there")
    elif fs is not None:
        check_positive(fs, "fs")

    pitch = _pitch(acc, axis)
    if method != "gating":
        return pitch

    accepted = gravity_gate(acc, xi=xi, gravity=gravity)
    if not np.all(accepted.any(axis=-1)):
        bad = tuple(int(i) for i in np.argwhere(~accepted.any(axis=-1))[0])
        where = f" (batch index {bad})" if bad else ""
        raise ValueError(f"no sample of acc has |a| within [g - xi, g + xi] = [{gravity - xi:.4g}, "
                         f"{gravity + xi:.4g}] m/s²{where}; increase xi or use method='lowpass'")
    return np.take_along_axis(pitch, last_received_index(accepted, backfill=True), axis=-1)


def _pitch(acc: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Eq. (6)/(7): ``arcsin(a·u / |a|)``."""
    ratio = fixed_order.dot(acc, axis) / np.linalg.norm(acc, axis=-1)
    return np.arcsin(np.clip(ratio, -1.0, 1.0))


def _lowpass(acc: np.ndarray, fs, cutoff_hz, order) -> np.ndarray:
    from scipy import signal

    if fs is None:
        raise ValueError("fs (Hz) is required for method='lowpass'")
    fs = check_positive(fs, "fs")
    cutoff_hz = check_positive(cutoff_hz, "cutoff_hz")
    if cutoff_hz >= fs / 2.0:
        raise ValueError(f"cutoff_hz must be below the Nyquist frequency fs/2 = {fs / 2.0:g} Hz, got {cutoff_hz!r}")
    check_count(order, "order")
    # Second-order sections: the (b, a) polynomial form loses the filter to rounding at high
    # orders or low cut-offs (order 8 at 0.05 Hz is unstable in it); cascaded biquads are not.
    sos = signal.butter(int(order), cutoff_hz, btype="low", fs=fs, output="sos")
    series = np.moveaxis(acc, -2, -1)                                   # (..., 3, T)
    zi_unit = signal.sosfilt_zi(sos)                                    # (S, 2), for a unit step
    zi = zi_unit.reshape((len(sos),) + (1,) * (series.ndim - 1) + (2,)) * series[None, ..., :1]
    # (S, ..., 3, 2): every section in its steady state for the first sample (no start-up transient)
    filtered, _ = signal.sosfilt(sos, series, axis=-1, zi=zi)
    return np.moveaxis(filtered, -1, -2)


# --- eqs. (8)–(10): the recursive chain --------------------------------------------------------


#: Per-user geometry of a chain of segments from the fixed origin outwards: segment lengths
#: (the paper's d) and device offsets from each segment's proximal joint (d′), metres.  The
#: package's one arm geometry, :class:`wsnlib.arm_model.ArmGeometry` (its new home), under
#: the name this module has always used; ``ArmChain(segment_lengths_m, device_offsets_m)``.
ArmChain = ArmGeometry

#: The paper's arm, as implied by Table 1 (not stated in the text): target 1 "in the middle of
#: the upper arm" at 15 cm from the shoulder → upper arm 0.30 m; target 2 "in the middle of the
#: forearm" at 42.5 cm from the shoulder with the arm straight → forearm 0.25 m, device at
#: 0.125 m from the elbow.  (Table 1's P5, a bent elbow, fits this to within 1 cm.)
PAPER_ARM_CHAIN = ArmChain(segment_lengths_m=(0.30, 0.25), device_offsets_m=(0.15, 0.125))


def _direction(heading: np.ndarray, pitch: np.ndarray) -> np.ndarray:
    """Unit vector ``(cos θ cos ψ, cos θ sin ψ, sin θ)`` of eqs. (9)–(10), shape (..., 3)."""
    cos_pitch = np.cos(pitch)
    return np.stack([cos_pitch * np.cos(heading), cos_pitch * np.sin(heading), np.sin(pitch)], axis=-1)


def _check_pitch(pitch, name: str) -> np.ndarray:
    pitch = as_float_array(pitch, name, min_ndim=2)
    limit = math.pi / 2.0
    if np.any(np.abs(pitch) > limit + 1e-9):
        bad = tuple(int(i) for i in np.argwhere(np.abs(pitch) > limit + 1e-9)[0])
        raise ValueError(f"{name} must lie in [-pi/2, pi/2] rad (eq. (7)); index {bad} holds {pitch[bad]!r}")
    return np.clip(pitch, -limit, limit)


def _check_chain(chain, n_segments: int, what: str) -> ArmChain:
    if not isinstance(chain, ArmChain):
        raise ValueError(f"chain must be an ArmChain, got {type(chain).__name__}")
    if chain.n_segments != n_segments:
        raise ValueError(f"{what} has {n_segments} segment(s) but chain has {chain.n_segments}")
    return chain


def _origin(origin, shape_time: tuple[int, ...]) -> np.ndarray:
    origin = as_float_array(origin, "origin", last_dim=3)
    try:
        return np.broadcast_to(origin, shape_time + (3,))
    except ValueError as exc:
        raise ValueError(f"origin has shape {origin.shape}, which does not fit {shape_time + (3,)}") from exc


def forward_chain(heading, pitch, chain: ArmChain, *, origin=(0.0, 0.0, 0.0)) -> dict[str, np.ndarray]:
    """Device and joint positions from known segment headings and pitches, eqs. (9)–(10).

    Useful for ground truth: ``recursive_chain(forward_chain(ψ, θ, c)["devices"], θ, c)``
    returns the same positions.

    Parameters
    ----------
    heading : array_like, shape (..., T, S)
        Segment headings ψ (rad), azimuth in the x–y plane (x right, y forward).
    pitch : array_like, shape (..., T, S)
        Segment pitches θ (rad) in ``[−π/2, π/2]``.  Broadcasts with ``heading``.
    chain : ArmChain
    origin : array_like, shape (3,) or (..., T, 3)
        Proximal joint of the first segment (the shoulder), metres.

    Returns
    -------
    dict
        ``"devices"``: ``(..., T, S, 3)`` device positions; ``"joints"``: ``(..., T, S, 3)``
        distal joint of each segment (elbow, wrist, …), metres.
    """
    heading = as_float_array(heading, "heading", min_ndim=2)
    pitch = _check_pitch(pitch, "pitch")
    try:
        shape = np.broadcast_shapes(heading.shape, pitch.shape)
    except ValueError as exc:
        raise ValueError(f"heading {heading.shape} and pitch {pitch.shape} do not broadcast") from exc
    chain = _check_chain(chain, shape[-1], "heading/pitch")
    direction = _direction(heading, pitch)                                # (..., T, S, 3)
    direction = np.broadcast_to(direction, shape + (3,))
    proximal = _origin(origin, shape[:-1])
    devices = np.empty(shape + (3,))
    joints = np.empty(shape + (3,))
    for s in range(chain.n_segments):
        devices[..., s, :] = proximal + chain.device_offsets_m[s] * direction[..., s, :]
        joints[..., s, :] = proximal + chain.segment_lengths_m[s] * direction[..., s, :]
        proximal = joints[..., s, :]
    return {"devices": devices, "joints": joints}


def recursive_chain(radio_positions, pitch, chain: ArmChain, *, origin=(0.0, 0.0, 0.0),
                    heading_tol_m: float = DEFAULT_HEADING_TOL_M) -> dict[str, np.ndarray]:
    """The paper's recursive estimation process, eqs. (8)–(10), over any chain (footnote 5).

    For segment ``s = 0, 1, …`` with proximal joint ``A`` (the origin for ``s = 0``, else the
    estimated distal joint of segment ``s − 1``):

    * eq. (8): ``ψ = atan2(y_D̂ − y_A, x_D̂ − x_A)`` from the radio estimate ``D̂`` of the device;
    * eq. (9): ``D̄ = A + d′ (cos θ cos ψ, cos θ sin ψ, sin θ)`` with the accelerometer pitch θ;
    * eq. (10): ``B = A + d (cos θ cos ψ, cos θ sin ψ, sin θ)``, the next ``A``.

    So the radio estimate contributes only its azimuth; distance from the joint and height
    come from the chain geometry and the pitch.

    Undefined heading: when ``D̂`` is (within ``heading_tol_m``) straight above or below ``A``,
    eq. (8) has no answer; the segment then keeps its heading from the latest earlier sample
    (along T) where it was defined, or 0 (pointing along +x) if there is none.  Only matters
    when ``|θ| < π/2``: at ``θ = ±π/2`` the heading does not move any point.

    Parameters
    ----------
    radio_positions : array_like, shape (..., T, S, 3)
        Radio (fingerprinting) position estimates ``D̂`` of each segment's device, metres,
        frame x right, y forward, z up, shoulder at ``origin``.
    pitch : array_like, shape (..., T, S)
        Segment pitches θ (rad) in ``[−π/2, π/2]``, e.g. from :func:`pitch_from_acc`.
        Broadcasts with ``radio_positions[..., 0]``.
    chain : ArmChain
        Segment lengths (d) and device offsets (d′), S segments.
    origin : array_like, shape (3,) or (..., T, 3)
        The fixed origin O (the shoulder), metres.
    heading_tol_m : float
        Horizontal distance (m) at or below which the heading is undefined;
        default :data:`DEFAULT_HEADING_TOL_M`.

    Returns
    -------
    dict
        * ``"devices"``: ``(..., T, S, 3)`` corrected device positions ``D̄`` (m);
        * ``"joints"``: ``(..., T, S, 3)`` distal joint of each segment ``B`` (elbow, wrist, …);
        * ``"heading"``: ``(..., T, S)`` heading ψ used (rad, in ``[0, 2π)``);
        * ``"heading_held"``: ``(..., T, S)`` bool, True where eq. (8) was undefined and the
          held (or zero) heading was used.
    """
    radio = as_float_array(radio_positions, "radio_positions", last_dim=3, min_ndim=3)
    pitch = _check_pitch(pitch, "pitch")
    try:
        shape = np.broadcast_shapes(radio.shape[:-1], pitch.shape)
    except ValueError as exc:
        raise ValueError(f"radio_positions {radio.shape} and pitch {pitch.shape} do not fit: "
                         "pitch must broadcast to (..., T, S)") from exc
    chain = _check_chain(chain, shape[-1], "radio_positions/pitch")
    heading_tol_m = check_nonnegative(heading_tol_m, "heading_tol_m")
    radio = np.broadcast_to(radio, shape + (3,))
    pitch = np.broadcast_to(pitch, shape)
    proximal = _origin(origin, shape[:-1])

    devices = np.empty(shape + (3,))
    joints = np.empty(shape + (3,))
    headings = np.empty(shape)
    held = np.empty(shape, dtype=bool)
    for s in range(chain.n_segments):
        delta = radio[..., s, :] - proximal                                    # (..., T, 3)
        defined = np.hypot(delta[..., 0], delta[..., 1]) > heading_tol_m       # (..., T)
        heading = np.mod(np.arctan2(delta[..., 1], delta[..., 0]), 2.0 * math.pi)   # eq. (8)
        heading = np.where(heading >= 2.0 * math.pi, 0.0, heading)              # mod can round up to 2π
        index = last_received_index(defined)
        heading = np.where(index >= 0, np.take_along_axis(heading, np.maximum(index, 0), axis=-1), 0.0)
        direction = _direction(heading, pitch[..., s])
        devices[..., s, :] = proximal + chain.device_offsets_m[s] * direction      # eq. (9)
        joints[..., s, :] = proximal + chain.segment_lengths_m[s] * direction      # eq. (10)
        headings[..., s] = heading
        held[..., s] = ~defined
        proximal = joints[..., s, :]
    return {"devices": devices, "joints": joints, "heading": headings, "heading_held": held}
