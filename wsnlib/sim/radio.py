"""RSS recordings of paper 002's testbed: packets, temporal randomness, the long RSS table, and the
sessions of paper 002's protocol (Sec. 4.1).

Turns a motion into RSS readings with the model of :mod:`wsnlib.sim.radio_channel` (whose
docstring gives the equations and the sources of every number): the deterministic budget of
:func:`wsnlib.sim.radio_channel.link_budget`, plus slow shadowing, Rician fading, interference
bursts, per-radio offsets, read noise, rounding and packet loss (:func:`simulate_rss`).

Each session builds an arm motion (:mod:`wsnlib.sim.arm_motion`) and records its RSS with
:func:`simulate_rss`.  :func:`static_session` holds the postures (the training and the online
static sessions); :func:`online_dynamic_session` performs the movements.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.signal import lfilter

from wsnlib._validation import check_positive, check_type
from wsnlib.io.rss import COLUMNS
from wsnlib.io.sidecar import check_name
from wsnlib.loss import gilbert_elliott
from wsnlib.sim.arm_motion import (
    ArmMotion,
    concatenate,
    direction_orientation,
    hold,
    jittered_direction,
    movement,
    transition,
)
from wsnlib.sim.body import User
from wsnlib.sim.radio_channel import RadioChannel, link_budget
from wsnlib.testbed import ANCHOR_NAMES, MOVEMENTS, POSTURES, TARGET_NAMES

# --------------------------------------------------------------------------------------------
# Random processes
# --------------------------------------------------------------------------------------------


def gauss_markov(n: int, rho: float, *, rng: np.random.Generator, shape=(), complex_valued: bool = False) -> np.ndarray:
    """Stationary unit-variance AR(1) sequences ``x_k = ρ x_{k−1} + √(1−ρ²) w_k`` along the last axis.

    Parameters
    ----------
    n : int
        Length.
    rho : float
        Lag-one correlation in [0, 1).
    rng : numpy.random.Generator
    shape : tuple
        Batch shape; output ``(*shape, n)``.
    complex_valued : bool
        Circular complex Gaussian (``E|x|² = 1``) instead of real.
    """
    if not 0.0 <= rho < 1.0:
        raise ValueError(f"rho must lie in [0, 1), got {rho!r}")
    size = tuple(shape) + (int(n),)
    w = rng.standard_normal(size)
    if complex_valued:
        w = (w + 1j * rng.standard_normal(size)) / np.sqrt(2.0)
    e = np.sqrt(1.0 - rho**2) * w
    e[..., 0] = w[..., 0]  # start in the stationary distribution
    return lfilter([1.0], [1.0, -rho], e, axis=-1)


def rician_fading_db(k_db, g: np.ndarray) -> np.ndarray:
    """Power gain (dB) ``20 log10 |√(K/(K+1)) + √(1/(K+1)) g|`` of Rician fading.

    ``k_db`` broadcasts against the complex scattered component ``g`` (unit mean power);
    ``k_db = inf`` gives 0 dB.  The mean power gain is 1 (0 dB in the linear mean).
    """
    k = 10.0 ** (np.asarray(k_db, dtype=float) / 10.0)
    with np.errstate(invalid="ignore"):
        los = np.where(np.isinf(k), 1.0, np.sqrt(k / (k + 1.0)))
        scatter = np.where(np.isinf(k), 0.0, np.sqrt(1.0 / (k + 1.0)))
    h = los + scatter * g
    return 20.0 * np.log10(np.maximum(np.abs(h), 1e-6))


def _burst_losses(n: int, fraction: float, mean_burst: float, low: float, high: float, rng, shape) -> np.ndarray:
    """Per-reading extra loss (dB) from Gilbert–Elliott bursts, one loss per burst, (*shape, n)."""
    if fraction <= 0.0:
        return np.zeros(tuple(shape) + (n,))
    bad = ~gilbert_elliott(n, fraction, mean_burst, rng=rng, shape=shape)
    starts = bad & ~np.concatenate([np.zeros(tuple(shape) + (1,), dtype=bool), bad[..., :-1]], axis=-1)
    burst_id = np.cumsum(starts, axis=-1)
    table = rng.uniform(low, high, tuple(shape) + (n + 1,))
    loss = np.take_along_axis(table, burst_id, axis=-1)
    return np.where(bad, loss, 0.0)


def _radio_offsets(user: User, channel: RadioChannel) -> tuple[np.ndarray, np.ndarray]:
    """Per-target transmit-power and per-anchor RSSI offsets (dB), fixed by the environment seed."""
    g = np.random.default_rng([user.environment_seed, 2])
    tx = g.normal(0.0, 1.0, len(TARGET_NAMES)) * channel.tx_power_offset_db
    rx = g.normal(0.0, 1.0, len(ANCHOR_NAMES)) * channel.rssi_offset_db
    return tx, rx


# --------------------------------------------------------------------------------------------
# Simulation
# --------------------------------------------------------------------------------------------


def packet_times(duration_s: float, packet_rate_hz: float, target: int, *, rng, jitter_s: float = 0.0,
                 start_s: float = 0.0) -> np.ndarray:
    """Transmission times (s) of ``target``'s packets: ``start + (k + target/2) / rate + jitter``.

    T2 is offset by half a period from T1 (the two targets interleave); times are rounded to
    1 µs (the precision of the recording format) and kept inside ``[start, start + duration)``.
    """
    rate = check_positive(packet_rate_hz, "packet_rate_hz")
    n = int(np.floor(check_positive(duration_s, "duration_s") * rate - 0.5 * target))
    t = (np.arange(max(n, 0)) + 0.5 * target) / rate
    if jitter_s > 0.0 and t.size:
        t = t + np.clip(rng.normal(0.0, jitter_s, t.size), -0.2 / rate, 0.2 / rate)
    t = np.clip(t, 0.0, duration_s - 1e-6)
    return np.round(start_s + t, 6)


def simulate_rss(motion: ArmMotion, user: User, *, rng: np.random.Generator, packet_rate_hz: float = 30.0,
                 channel: RadioChannel | None = None, session: str = "session", start_s: float = 0.0) -> pd.DataFrame:
    """RSS readings of both targets at all anchors while the arm follows ``motion``.

    Parameters
    ----------
    motion : ArmMotion
        Arm motion, time 0 = start of the recording.
    user : User
        Body, anchors and radio environment (``environment_seed``, ``day``).
    rng : numpy.random.Generator
        Draws the temporal randomness of this recording (fading, slow shadowing,
        interference, losses, jitter, read noise).  The spatial field and the radio offsets
        come from ``user.environment_seed`` instead, so that every session of a user shares
        them.
    packet_rate_hz : float
        Packets per second per target (paper 002: "around 30 pck/s").
    channel : RadioChannel, optional
        Default :class:`RadioChannel()`.
    session : str
        Session name written to the ``session`` column.
    start_s : float
        Time stamp (s) of the motion's time 0.

    Returns
    -------
    pandas.DataFrame
        The long table of :mod:`wsnlib.io.rss` (columns :data:`wsnlib.io.rss.COLUMNS`), one row per
        received (packet, anchor), ordered by time, target, anchor; ``rss_dbm`` int64;
        ``x_m, y_m, z_m`` the target's true position on the arm axis (shoulder frame).
        ``df.attrs`` holds ``packet_rate_hz`` and ``anchor_positions_m``
        ``{user: {session: {anchor: [x, y, z]}}}`` for :func:`wsnlib.io.rss.write_rss`.
    """
    channel = RadioChannel() if channel is None else channel
    check_type(motion, ArmMotion, "motion")
    check_type(user, User, "user")
    check_name(session, "session")
    rate = check_positive(packet_rate_hz, "packet_rate_hz")
    dt = 1.0 / rate
    tx_offset, rssi_offset = _radio_offsets(user, channel)
    n_anchors = len(ANCHOR_NAMES)
    frames = []
    for target in range(len(TARGET_NAMES)):
        t = packet_times(motion.total_duration_s, rate, target, rng=rng, jitter_s=channel.timing_jitter_s)
        n = t.size
        if n == 0:
            continue
        kin = motion.kinematics(t, user)
        budget = link_budget(kin, user, target, channel)
        power = budget.mean_rx_dbm + tx_offset[target]  # (n, 7)
        if channel.slow_sigma_db > 0.0:
            rho = float(np.exp(-dt / channel.slow_time_s))
            power = power + channel.slow_sigma_db * gauss_markov(n, rho, rng=rng, shape=(n_anchors,)).T
        if np.isfinite(budget.k_factor_db).any():
            rho = float(np.exp(-dt / channel.coherence_time_s))
            g = gauss_markov(n, rho, rng=rng, shape=(n_anchors,), complex_valued=True).T
            power = power + rician_fading_db(budget.k_factor_db, g)
        lo, hi = channel.interference_loss_db
        power = power - _burst_losses(n, channel.interference_fraction, channel.interference_mean_burst, lo, hi, rng,
                                      (n_anchors,)).T
        received = power >= channel.sensitivity_dbm
        if channel.link_loss_rate > 0.0:
            received &= gilbert_elliott(n, channel.link_loss_rate, channel.link_loss_mean_burst, rng=rng,
                                        shape=(n_anchors,)).T
        if channel.tx_loss_rate > 0.0:
            received &= (rng.random(n) >= channel.tx_loss_rate)[:, None]
        rssi = power + rssi_offset[None, :] + channel.rssi_noise_db * rng.standard_normal(power.shape)
        rssi = np.minimum(np.rint(rssi), channel.rssi_max_dbm).astype(np.int64)
        rows, cols = np.nonzero(received)
        pos = kin.pos[target, rows, :]
        frames.append(pd.DataFrame({
            "time_s": t[rows] + float(start_s), "user": user.name, "session": session, "target": TARGET_NAMES[target],
            "anchor": np.asarray(ANCHOR_NAMES, dtype=object)[cols], "rss_dbm": rssi[rows, cols],
            "label": kin.label[rows], "x_m": pos[:, 0], "y_m": pos[:, 1], "z_m": pos[:, 2]}))
    df = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame({c: [] for c in COLUMNS})
    df["time_s"] = np.round(df["time_s"].to_numpy(dtype=float), 6)
    df = df.sort_values(["time_s", "target", "anchor"], kind="stable", ignore_index=True)
    df = df.astype({"user": object, "session": object, "target": object, "anchor": object, "label": object,
                    "rss_dbm": np.int64})
    df.attrs["packet_rate_hz"] = rate
    df.attrs["anchor_positions_m"] = {user.name: {session: user.anchor_dict()}}
    return df


def concat_rss(frames) -> pd.DataFrame:
    """Concatenate RSS tables (sessions, users), merging their ``attrs`` (anchor positions).

    All frames must share the same ``packet_rate_hz`` attribute.
    """
    frames = list(frames)
    if not frames:
        raise ValueError("concat_rss needs at least one table")
    rates = {f.attrs.get("packet_rate_hz") for f in frames}
    if len(rates) != 1:
        raise ValueError(f"tables have different packet_rate_hz attributes: {sorted(map(str, rates))}")
    positions: dict = {}
    for f in frames:
        for user, sessions in f.attrs.get("anchor_positions_m", {}).items():
            positions.setdefault(user, {}).update(sessions)
    out = pd.concat(frames, ignore_index=True)
    out.attrs = {"packet_rate_hz": rates.pop(), "anchor_positions_m": positions}
    return out


# --------------------------------------------------------------------------------------------
# Sessions of paper 002's protocol
# --------------------------------------------------------------------------------------------


def _static_motion(rng, postures, hold_s, transition_s, jitter_deg):
    pieces = []
    q_prev = None
    for posture in postures:
        direction = jittered_direction(posture, jitter_deg, rng)
        q = direction_orientation(direction)
        if q_prev is not None:
            pieces.append(transition(q_prev, q, transition_s))
        pieces.append(hold(posture, hold_s, label=posture, q_start=q))
        q_prev = q
    return concatenate(pieces)


def static_session(user: User, *, rng: np.random.Generator, hold_s: float, session: str, transition_s: float = 3.0,
                   posture_jitter_deg: float = 2.0, packet_rate_hz: float = 30.0, channel: RadioChannel | None = None,
                   include_transitions: bool = False) -> pd.DataFrame:
    """The user holds P1 … P5 for ``hold_s`` each, moving between them in ``transition_s``.

    Paper 002's training phase holds each posture 30 s (~1000 fingerprint vectors per target),
    session ``"training"``; its online phase, static part, holds them again on another day
    (``user.moved(rng)``), session ``"online_static"``.  Rows recorded while moving are
    labelled ``"transition"`` and dropped unless ``include_transitions``.  Each hold is the
    posture turned by a random rotation of ``posture_jitter_deg`` rms per axis (the user's
    imprecision; *assumed* 2°); the recorded positions are the true, jittered ones.  From
    ``rng``: the jitter of every posture, then the RSS (:func:`simulate_rss`).

    Parameters
    ----------
    user : User
        Pass ``user.moved(rng)`` for another day (moved anchors, partly new environment).
    rng : numpy.random.Generator
    hold_s : float
        Seconds each posture is held.
    session : str
        Session name written to the ``session`` column.
    transition_s, posture_jitter_deg, packet_rate_hz, channel, include_transitions
        As above; ``channel`` default :class:`RadioChannel()`.

    Returns
    -------
    pandas.DataFrame
        See :func:`simulate_rss`; labels ``"P1"`` … ``"P5"``.
    """
    motion = _static_motion(rng, POSTURES, check_positive(hold_s, "hold_s"),
                            check_positive(transition_s, "transition_s"), posture_jitter_deg)
    df = simulate_rss(motion, user, rng=rng, packet_rate_hz=packet_rate_hz, channel=channel, session=session)
    if not include_transitions:
        attrs = df.attrs
        df = df[df["label"] != "transition"].reset_index(drop=True)
        df.attrs = attrs
    return df


def movement_label(index: int, name: str) -> str:
    """Label of the ``index``-th movement of a dynamic session, e.g. ``"M1_lower_P2_P3_P1"``."""
    return f"M{int(index)}_{name}"


def online_dynamic_motion(*, rng: np.random.Generator, durations_s=None, repetitions: int = 2, hold_s: float = 1.0,
                          transition_s: float = 2.0) -> ArmMotion:
    """The arm motion of :func:`online_dynamic_session` (the paper's sequence of movements).

    For each movement: move (``"transition"``) to its start posture unless already there,
    hold it ``hold_s`` (label = posture), perform the movement at constant speed (label
    :func:`movement_label`), hold the end posture ``hold_s``.  ``durations_s`` (one per
    movement, ``4 · repetitions``) defaults to uniform draws in [2, 4] s (paper 002: "typically
    … 2–4 s").
    """
    names = list(MOVEMENTS) * int(repetitions)
    if durations_s is None:
        durations = rng.uniform(2.0, 4.0, len(names))
    else:
        durations = np.asarray(durations_s, dtype=float)
        if durations.shape != (len(names),):
            raise ValueError(f"durations_s must have {len(names)} entries, got shape {durations.shape}")
    pieces = []
    current = None
    for k, (name, duration) in enumerate(zip(names, durations, strict=True), start=1):
        first, last = MOVEMENTS[name][0], MOVEMENTS[name][-1]
        if current is not None and current != first:
            pieces.append(transition(current, first, transition_s))
        if current != first:
            pieces.append(hold(first, hold_s))
        pieces.append(movement(name, float(duration), label=movement_label(k, name)))
        pieces.append(hold(last, hold_s))
        current = last
    return concatenate(pieces)


def online_dynamic_session(user: User, *, rng: np.random.Generator, durations_s=None, repetitions: int = 2,
                           hold_s: float = 1.0, transition_s: float = 2.0, packet_rate_hz: float = 30.0,
                           channel: RadioChannel | None = None, session: str = "online_dynamic") -> pd.DataFrame:
    """Online phase, dynamic part: the four movements, the sequence done twice (8 movements).

    Labels: ``"M1_lower_P2_P3_P1"`` … ``"M8_horizontal_P3_P4"`` during the movements (index
    and name, :func:`movement_label`), the posture name during the short holds around them,
    ``"transition"`` in between.  See :func:`online_dynamic_motion` and :func:`simulate_rss`.
    """
    motion = online_dynamic_motion(rng=rng, durations_s=durations_s, repetitions=repetitions, hold_s=hold_s,
                                   transition_s=transition_s)
    return simulate_rss(motion, user, rng=rng, packet_rate_hz=packet_rate_hz, channel=channel, session=session)
