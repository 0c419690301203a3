"""Deterministic link budget of paper 002's radio links from the arm's kinematics and the body.

Path loss, body shadowing, antenna gains and the quenched spatial shadowing field of the model
in :mod:`wsnlib.sim.radio_channel` (whose docstring gives the equations and sources), for one
target at the times of an :class:`wsnlib.arm_model.ArmKinematics` (layout ``(node, T, C)``).
Shoulder frame, metres, dB.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from wsnlib import fixed_order
from wsnlib import quaternion as Q
from wsnlib.arm_model import ArmKinematics
from wsnlib.sim.body_solids import body_solids, chord_length
from wsnlib.sim.radio_channel import RadioChannel
from wsnlib.sim.users import User

#: Solids that shadow at most :attr:`RadioChannel.limb_shadow_cap_db`.
LIMB_SOLIDS = frozenset({"neck", "left_arm", "upper_arm", "forearm"})


def antenna_positions(kin: ArmKinematics, user: User, standoff_m: float = 0.01) -> np.ndarray:
    """Radio antenna position (2, T, 3) of T1 and T2 (m): on the lateral skin of their segment.

    The node sits on the segment's body −y side (lateral in the reference posture, arm
    forward), ``radius + standoff_m`` from the device point ``kin.pos`` on the arm axis
    (:mod:`wsnlib.sim.body`, "Body for shadowing").
    """
    if not isinstance(kin, ArmKinematics):
        raise ValueError(f"kin must be an ArmKinematics, got {type(kin).__name__}")
    lateral = Q.rotate(kin.quat, np.array([0.0, -1.0, 0.0]))  # (2, T, 3)
    radii = np.array([user.body.upper_arm_radius_m, user.body.forearm_radius_m]) + standoff_m
    return kin.pos + lateral * radii[:, None, None]


def dipole_gain_db(link_direction, antenna_axis, peak_dbi: float = 0.0, floor_db: float = -10.0) -> np.ndarray:
    """Dipole-like gain ``peak + 10 log10 max(sin²ψ, 10^(floor/10))`` (dBi).

    ψ is the angle between ``link_direction`` and ``antenna_axis`` (both (..., 3), any
    length): maximum broadside (ψ = 90°), ``peak + floor`` along the axis.
    """
    v = np.asarray(link_direction, dtype=float)
    a = np.asarray(antenna_axis, dtype=float)
    cos = np.sum(v * a, axis=-1) / (np.linalg.norm(v, axis=-1) * np.linalg.norm(a, axis=-1))
    sin2 = np.clip(1.0 - cos**2, 0.0, 1.0)
    return peak_dbi + 10.0 * np.log10(np.maximum(sin2, 10.0 ** (floor_db / 10.0)))


@dataclass(frozen=True, eq=False)
class LinkBudget:
    """Deterministic part of the links of one target to the 7 anchors, shape (T, 7) each.

    Attributes
    ----------
    distance_m : antenna–anchor distance (m).
    chord_m : length of the straight link inside the body (m).
    nlos : bool, the link crosses the body (``chord_m > 0``).
    worn : bool (7,), the anchor is worn (on-body link).
    path_loss_db : log-distance path loss (on-body LOS or off-body model).
    body_loss_db : shadowing by the body (capped, see the module docstring).
    total_loss_db : ``path_loss_db + body_loss_db``, for on-body links power-summed with the
        room-reflected path (``RadioChannel.onbody_room_path_loss_db``).
    nlos_weight : ``body_loss_db / cap`` in [0, 1] (0 LOS, 1 fully shadowed).
    gain_target_db, gain_anchor_db : antenna gains (dBi).
    shadow_sigma_db : σ of the spatial field for the link (LOS → NLOS σ by ``nlos_weight``).
    shadow_db : spatial shadowing ``σ · X`` (dB).
    k_factor_db : Rician K of the link.
    mean_rx_dbm : ``P_tx − total_loss + G_t + G_a + shadow`` (dBm): the received power
        without temporal effects and radio offsets.
    """

    distance_m: np.ndarray
    chord_m: np.ndarray
    nlos: np.ndarray
    worn: np.ndarray
    path_loss_db: np.ndarray
    body_loss_db: np.ndarray
    total_loss_db: np.ndarray
    nlos_weight: np.ndarray
    gain_target_db: np.ndarray
    gain_anchor_db: np.ndarray
    shadow_sigma_db: np.ndarray
    shadow_db: np.ndarray
    k_factor_db: np.ndarray
    mean_rx_dbm: np.ndarray


def _shadow_field(
    anchors: np.ndarray, antenna: np.ndarray, target: int, user: User, channel: RadioChannel
) -> np.ndarray:
    """Unit-variance smooth random field X(anchor, antenna), (T, 7) (module docstring)."""
    m = channel.shadow_features
    x = np.concatenate(
        [
            np.broadcast_to(anchors[None], antenna.shape[:1] + anchors.shape),
            np.broadcast_to(antenna[:, None, :], antenna.shape[:1] + anchors.shape),
        ],
        axis=-1,
    )  # (T, 7, 6)
    out = np.zeros(x.shape[:2])
    beta = channel.day_decorrelation
    for a in range(anchors.shape[0]):
        parts = [(np.sqrt(1.0 - beta), (user.environment_seed, 0, target, a))]
        if beta > 0.0:
            parts.append((np.sqrt(beta), (user.environment_seed, 1, user.day, target, a)))
        for weight, key in parts:
            g = np.random.default_rng(list(key))
            omega = g.normal(0.0, 1.0 / channel.shadow_length_m, (m, 6))
            phase = g.uniform(0.0, 2.0 * np.pi, m)
            out[:, a] += weight * np.sqrt(2.0 / m) * np.cos(fixed_order.matmul(x[:, a], omega.T) + phase).sum(axis=-1)
    return out


def link_budget(kin: ArmKinematics, user: User, target: int, channel: RadioChannel | None = None) -> LinkBudget:
    """Deterministic link budget of target ``target`` (0 = T1, 1 = T2) at the times of ``kin``.

    Parameters
    ----------
    kin : wsnlib.arm_model.ArmKinematics
        Arm state (e.g. ``motion.kinematics(t, user)``), layout ``(node, T, C)``.
    user : User
    target : int
        0 or 1.
    channel : RadioChannel, optional
        Default :class:`RadioChannel()`.

    Returns
    -------
    LinkBudget
        Arrays of shape (T, 7).
    """
    channel = RadioChannel() if channel is None else channel
    if target not in (0, 1):
        raise ValueError(f"target must be 0 (T1) or 1 (T2), got {target!r}")
    if not isinstance(kin, ArmKinematics):
        raise ValueError(f"kin must be an ArmKinematics, got {type(kin).__name__}")
    antenna = antenna_positions(kin, user)[target]  # (T, 3)
    directions = kin.directions  # (2, T, 3)
    axis = directions[target]  # (T, 3): the segment carries the antenna axis
    anchors = user.anchor_positions_m  # (7, 3)
    link = anchors[None, :, :] - antenna[:, None, :]  # (T, 7, 3): target → anchor
    distance = np.linalg.norm(link, axis=-1)

    solids = body_solids(user, directions[0])
    chord_trunk = np.zeros_like(distance)
    chord_limb = np.zeros_like(distance)
    p = antenna[:, None, :]
    q = anchors[None, :, :]
    for solid in solids:
        if solid.base.ndim == 2:  # moving (arm) solids: add the anchor axis for broadcasting
            solid = dataclasses.replace(
                solid, base=solid.base[:, None, :], axis=solid.axis[:, None, :], ref=solid.ref[:, None, :]
            )
        c = chord_length(p, q, solid, trim_m=channel.body_trim_m)
        if solid.name in LIMB_SOLIDS:
            chord_limb = chord_limb + c
        else:
            chord_trunk = chord_trunk + c

    worn = user.worn
    per_m = channel.creeping_db_per_cm * 100.0 * 0.5 * np.pi
    shadowing = per_m * chord_trunk + np.minimum(per_m * chord_limb, channel.limb_shadow_cap_db)
    onbody_cap = np.maximum(channel.onbody_nlos.mean_db(distance) - channel.onbody_los.mean_db(distance), 0.0)
    cap = np.where(worn[None, :], onbody_cap, channel.offbody_shadow_cap_db)
    body_loss = np.minimum(shadowing, cap)
    weight = np.where(cap > 0.0, body_loss / np.where(cap > 0.0, cap, 1.0), 0.0)
    path_loss = np.where(worn[None, :], channel.onbody_los.mean_db(distance), channel.offbody.mean_db(distance))
    direct = path_loss + body_loss
    via_room = -10.0 * np.log10(10.0 ** (-direct / 10.0) + 10.0 ** (-channel.onbody_room_path_loss_db / 10.0))
    total_loss = np.where(worn[None, :], via_room, direct)
    sigma = np.where(
        worn[None, :],
        (1.0 - weight) * channel.onbody_los.sigma_db + weight * channel.onbody_nlos.sigma_db,
        channel.offbody.sigma_db,
    )
    shadow = sigma * _shadow_field(anchors, antenna, target, user, channel)
    gain_t = dipole_gain_db(link, axis[:, None, :], channel.antenna_peak_gain_dbi, channel.antenna_floor_db)
    gain_a = dipole_gain_db(
        -link, user.anchor_axes[None, :, :], channel.antenna_peak_gain_dbi, channel.antenna_floor_db
    )
    k_los, k_shadowed = channel.fading_k_onbody_los_db, channel.fading_k_db
    if np.isfinite(k_los) and np.isfinite(k_shadowed):
        k_onbody = k_los + weight * (k_shadowed - k_los)
    else:
        k_onbody = np.where(weight > 0.0, k_shadowed, k_los)
    k_db = np.where(worn[None, :], k_onbody, k_shadowed)
    mean_rx = channel.tx_power_dbm - total_loss + gain_t + gain_a + shadow
    return LinkBudget(
        distance_m=distance,
        chord_m=chord_trunk + chord_limb,
        nlos=(chord_trunk + chord_limb) > 0.0,
        worn=worn,
        path_loss_db=path_loss,
        body_loss_db=body_loss,
        total_loss_db=total_loss,
        nlos_weight=weight,
        gain_target_db=gain_t,
        gain_anchor_db=gain_a,
        shadow_sigma_db=sigma,
        shadow_db=shadow,
        k_factor_db=np.broadcast_to(k_db, distance.shape).copy(),
        mean_rx_dbm=mean_rx,
    )


__all__ = ["LIMB_SOLIDS", "LinkBudget", "antenna_positions", "dipole_gain_db", "link_budget"]
