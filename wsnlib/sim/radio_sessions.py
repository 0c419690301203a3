"""Sessions of paper 002's protocol (Sec. 4.1): static postures (training, online) and movements.

Each session builds an arm motion (:mod:`wsnlib.sim.arm_motion`) and records its RSS with
:func:`wsnlib.sim.radio_rss.simulate_rss`.  :func:`static_session` is the one static session;
:func:`training_session` and :func:`online_static_session` are it with the paper's training and
online defaults.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnlib._validation import check_positive
from wsnlib.sim.arm_motion import (
    ArmMotion,
    concatenate,
    direction_orientation,
    hold,
    jittered_direction,
    movement,
    transition,
)
from wsnlib.sim.radio_channel import RadioChannel
from wsnlib.sim.radio_rss import simulate_rss
from wsnlib.sim.users import User
from wsnlib.testbed import ANCHOR_NAMES, MOVEMENTS, POSTURES


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


def static_session(
    user: User,
    *,
    rng: np.random.Generator,
    hold_s: float,
    session: str,
    transition_s: float = 3.0,
    posture_jitter_deg: float = 2.0,
    packet_rate_hz: float = 30.0,
    channel: RadioChannel | None = None,
    include_transitions: bool = False,
) -> pd.DataFrame:
    """The user holds P1 … P5 for ``hold_s`` each, moving between them in ``transition_s``.

    Rows recorded while moving are labelled ``"transition"`` and dropped unless
    ``include_transitions``.  Each hold is the posture turned by a random rotation of
    ``posture_jitter_deg`` rms per axis (the user's imprecision; *assumed* 2°); the recorded
    positions are the true, jittered ones.  From ``rng``: the jitter of every posture, then the
    RSS (:func:`wsnlib.sim.radio_rss.simulate_rss`).

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
        See :func:`wsnlib.sim.radio_rss.simulate_rss`; labels ``"P1"`` … ``"P5"``.
    """
    motion = _static_motion(
        rng,
        POSTURES,
        check_positive(hold_s, "hold_s"),
        check_positive(transition_s, "transition_s"),
        posture_jitter_deg,
    )
    df = simulate_rss(motion, user, rng=rng, packet_rate_hz=packet_rate_hz, channel=channel, session=session)
    if not include_transitions:
        attrs = df.attrs
        df = df[df["label"] != "transition"].reset_index(drop=True)
        df.attrs = attrs
    return df


def training_session(
    user: User,
    *,
    rng: np.random.Generator,
    hold_s: float = 30.0,
    transition_s: float = 3.0,
    posture_jitter_deg: float = 2.0,
    packet_rate_hz: float = 30.0,
    channel: RadioChannel | None = None,
    session: str = "training",
    include_transitions: bool = False,
) -> pd.DataFrame:
    """Training phase: :func:`static_session` with the paper's 30 s per posture (~1000
    fingerprint vectors per target), session ``"training"``."""
    return static_session(
        user,
        rng=rng,
        hold_s=hold_s,
        session=session,
        transition_s=transition_s,
        posture_jitter_deg=posture_jitter_deg,
        packet_rate_hz=packet_rate_hz,
        channel=channel,
        include_transitions=include_transitions,
    )


def online_static_session(
    user: User,
    *,
    rng: np.random.Generator,
    hold_s: float = 10.0,
    transition_s: float = 3.0,
    posture_jitter_deg: float = 2.0,
    packet_rate_hz: float = 30.0,
    channel: RadioChannel | None = None,
    session: str = "online_static",
    include_transitions: bool = False,
) -> pd.DataFrame:
    """Online phase, static part: :func:`static_session` with ``hold_s`` 10 s (not given in the
    paper, *assumed*), session ``"online_static"``; pass ``user.moved(rng)`` for another day."""
    return static_session(
        user,
        rng=rng,
        hold_s=hold_s,
        session=session,
        transition_s=transition_s,
        posture_jitter_deg=posture_jitter_deg,
        packet_rate_hz=packet_rate_hz,
        channel=channel,
        include_transitions=include_transitions,
    )


def movement_label(index: int, name: str) -> str:
    """Label of the ``index``-th movement of a dynamic session, e.g. ``"M1_lower_P2_P3_P1"``."""
    return f"M{int(index)}_{name}"


def online_dynamic_motion(
    *,
    rng: np.random.Generator,
    durations_s=None,
    repetitions: int = 2,
    hold_s: float = 1.0,
    transition_s: float = 2.0,
) -> ArmMotion:
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


def online_dynamic_session(
    user: User,
    *,
    rng: np.random.Generator,
    durations_s=None,
    repetitions: int = 2,
    hold_s: float = 1.0,
    transition_s: float = 2.0,
    packet_rate_hz: float = 30.0,
    channel: RadioChannel | None = None,
    session: str = "online_dynamic",
) -> pd.DataFrame:
    """Online phase, dynamic part: the four movements, the sequence done twice (8 movements).

    Labels: ``"M1_lower_P2_P3_P1"`` … ``"M8_horizontal_P3_P4"`` during the movements (index
    and name, :func:`movement_label`), the posture name during the short holds around them,
    ``"transition"`` in between.  See :func:`online_dynamic_motion` and :func:`simulate_rss`.
    """
    motion = online_dynamic_motion(
        rng=rng, durations_s=durations_s, repetitions=repetitions, hold_s=hold_s, transition_s=transition_s
    )
    return simulate_rss(motion, user, rng=rng, packet_rate_hz=packet_rate_hz, channel=channel, session=session)


def posture_mean_rss(df: pd.DataFrame, target: str = "T1") -> pd.DataFrame:
    """Mean RSS (dBm) per anchor (rows) and label (columns) of one target — a quick look table."""
    sub = df[df["target"] == target]
    table = sub.pivot_table(index="anchor", columns="label", values="rss_dbm", aggfunc="mean")
    return table.reindex(index=[a for a in ANCHOR_NAMES if a in table.index])


__all__ = [
    "movement_label",
    "online_dynamic_motion",
    "online_dynamic_session",
    "online_static_session",
    "posture_mean_rss",
    "static_session",
    "training_session",
]
