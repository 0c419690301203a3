"""RSS recordings of paper 002's testbed: 2 targets on the arm × 7 anchors, IEEE 802.15.4 at 2.4 GHz.

Each target broadcasts ~30 packets/s (paper 002, Sec. 4.1); every anchor receives each
packet or not and reports an integer RSS in dBm.  The received power of link (target ``i``,
anchor ``a``) for a packet at time ``t`` is::

    P = P_tx + δ_tx,i − L(d) + G_i(ψ_i) + G_a(ψ_a) + σ·X(anchor, antenna)
        + S_ia(t) + F_ia(t) − I_ia(t)

    L(d) = PL(d) + L_body                               room anchors (off-body links)
    L(d) = −10 log10(10^(−(PL(d) + L_body)/10) + 10^(−L_room/10))   worn anchors (on-body)

    RSS = round(P + δ_rssi,a + w)      reported only if P >= sensitivity and the packet is
                                       not lost otherwise (random and bursty loss)

* ``PL(d) = PL0 + 10 n log10(d / d0)``: log-distance path loss, on-body parameters for worn
  anchors, off-body parameters for room anchors (:class:`PathLossModel`).
* ``L_body``: body shadowing from the geometry of :mod:`wsnlib.sim.body`.  The straight link
  is intersected with the body solids (torso, legs, neck, head, both arms); a chord of
  length ``c`` inside the body is bypassed by a creeping wave along roughly half the
  circumference of a circle of diameter ``c``, ``π c / 2``, attenuated by
  ``creeping_db_per_cm``.  On-body links are LOS when nothing is crossed; the loss is capped
  at the NLOS − LOS difference of the on-body models at that distance (a fully shadowed
  on-body link follows the NLOS fit, which already contains the creeping loss around the
  torso).  Off-body links are capped at ``offbody_shadow_cap_db`` (reflections in the room
  fill the shadow).  Limbs (arms, neck) add at most ``limb_shadow_cap_db``.
* ``L_room``: on-body links also receive the wave reflected by the room
  (``onbody_room_path_loss_db``), power-summed with the direct path, so a fully shadowed
  on-body link beyond ~0.5 m does not follow the steep NLOS fit to zero.
* ``G(ψ)``: dipole-like antenna pattern ``G_peak + 10 log10 max(sin²ψ, floor)``, ψ the
  angle between the link and the antenna axis.  A target's antenna axis runs along its arm
  segment, so the gain changes as the segment turns.
* ``X``: quenched spatial shadowing, a smooth Gaussian random field of the anchor and target
  antenna positions with unit variance and correlation length ``shadow_length_m`` (random
  Fourier features of a squared-exponential kernel), scaled by the model's σ.  It is fixed
  by ``User.environment_seed``; a later day (``User.day``) replaces a fraction
  ``day_decorrelation`` of its variance (furniture, people), and moved anchors evaluate it
  elsewhere.  This is what makes a fingerprint position-specific.
* ``S``: slow temporal shadowing per link, Gauss–Markov in dB (people and body sway).
* ``F``: small-scale fading, Rician with factor K, the scattered part a complex Gauss–Markov
  (AR(1)) process per link at the packet rate with correlation time ``coherence_time_s``.
* ``I``: interference/obstruction bursts (people crossing, Wi-Fi): a Gilbert–Elliott state
  per link; in the bad state the reading drops by a per-burst loss drawn uniformly in
  ``interference_loss_db``.
* ``δ_tx``, ``δ_rssi``: per-radio transmit-power and RSSI offsets (hardware; fixed by
  ``environment_seed``), ``w`` RSSI read noise; rounding to 1 dBm (CC2420 reports integers).

Packets are lost below the sensitivity, at random per link (Gilbert–Elliott bursts) and at
random for all anchors at once (a collision at the transmitter).

Sources and status of the numbers (every :class:`RadioChannel` field says which applies)
-------------------------------------------------------------------------------------------
*quoted* = seen in a third-party document found during this work (named); *unverified* =
from the literature as recalled in the task brief, not found in any source consulted (the
search corpus had no text of these papers); *derived* = computed from other numbers here;
*assumed* = our modelling choice, with the reasoning.

* [Reusens2009] E. Reusens, W. Joseph, B. Latré, B. Braem, G. Vermeeren, E. Tanghe,
  L. Martens, I. Moerman, C. Blondia, "Characterization of on-body communication channel
  and energy efficient topology design for wireless body area networks", IEEE Trans. Inf.
  Technol. Biomed. 13(6):933–945, 2009: on-body path loss at 2.45 GHz, LOS (along the
  torso) and NLOS (around the torso).  *Unverified*, including the reference distance
  d0 = 10 cm.
* [IRACON2019] IRACON (COST CA15104) overview, ITU Journal ICT Discoveries 2(1), 2019:
  indoor off-body path-loss exponent ≈ 1.7, σ ≈ 1.2 dB.  *Unverified*.
* [CC2420] Texas Instruments/Chipcon CC2420 datasheet SWRS041: maximum output power 0 dBm,
  receiver sensitivity −95 dBm (typ.), RSSI accuracy ±6 dB, integer RSSI register.  The
  datasheet was located but its electrical-specification table not read: 0 dBm is *quoted*
  (``TXPOWER_MAX 0 // dBm`` in the CC2420 constants of the open-source simulator
  github.com/lequana2/wsn-energy); −95 dBm and ±6 dB are *unverified*.  SunSPOTs use the
  CC2420 (paper 002 ref. [25]).
* [EURASIP2014] "Time-varying on-body wireless channel model during walking", EURASIP J.
  Wireless Commun. Netw. 2014:29, Table 5: Rice K-factor 7 dB at 2.4 GHz as a simulation
  parameter; *quoted*.
* Clarke's coherence time ``T_c ≈ 0.423 / f_D`` (T. S. Rappaport, *Wireless
  Communications*, 2nd ed., eq. 5.40.c; recalled).
* Creeping waves around the torso: A. Chandra, A. J. Johansson, "An analytical link-loss
  model for on-body propagation around the body based on elliptical approximation of the
  torso with arms' influence included", IEEE Antennas Wireless Propag. Lett. 12:528–531,
  2013 (bibliographic record seen; the attenuation value is *assumed*, see the field).

The module holds the channel's parameters (:class:`PathLossModel`, :class:`RadioChannel`); its
deterministic part, the link budget from the arm's kinematics and the body (:func:`link_budget`:
path loss, body shadowing, antenna gains and the spatial shadowing field for one target at the
times of an :class:`wsnlib.arm_model.ArmKinematics`); the packets with their temporal
randomness, turned into the long RSS table (:func:`simulate_rss`); and the sessions of paper
002's protocol (Sec. 4.1), each an arm motion (:mod:`wsnlib.sim.arm_motion`) recorded with
:func:`simulate_rss`: :func:`static_session` holds the postures (the training and the online
static sessions), :func:`online_dynamic_session` performs the movements.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnlib import fixed_order
from wsnlib import quaternion as Q
from wsnlib._validation import check_count, check_fields, check_positive, check_type
from wsnlib.arm_model import ArmKinematics
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
from wsnlib.sim.body import User, body_solids, chord_length
from wsnlib.testbed import ANCHOR_NAMES, MOVEMENTS, POSTURES, TARGET_NAMES

#: Speed of light (m/s).
SPEED_OF_LIGHT = 299_792_458.0


def free_space_loss_db(distance_m, frequency_hz: float) -> np.ndarray:
    """Friis free-space path loss ``20 log10(4π d / λ)`` (dB) between isotropic antennas."""
    wavelength = SPEED_OF_LIGHT / check_positive(frequency_hz, "frequency_hz")
    return 20.0 * np.log10(4.0 * np.pi * np.asarray(distance_m, dtype=float) / wavelength)


@dataclass(frozen=True)
class PathLossModel:
    """Log-distance path loss ``PL(d) = PL0 + 10 n log10(d / d0)`` with log-normal spread σ.

    Parameters
    ----------
    pl0_db : float
        Path loss at the reference distance (dB).
    exponent : float
        Path-loss exponent n.
    sigma_db : float
        Standard deviation of the location-dependent shadowing around the fit (dB).
    d0_m : float
        Reference distance (m).
    """

    pl0_db: float
    exponent: float
    sigma_db: float
    d0_m: float

    def __post_init__(self):
        object.__setattr__(self, "pl0_db", float(self.pl0_db))
        check_fields(self, positive=("exponent", "d0_m"), nonnegative=("sigma_db",))

    def mean_db(self, distance_m) -> np.ndarray:
        """Mean path loss (dB) at ``distance_m`` (clipped below at ``d0 / 4``)."""
        d = np.maximum(np.asarray(distance_m, dtype=float), 0.25 * self.d0_m)
        return self.pl0_db + 10.0 * self.exponent * np.log10(d / self.d0_m)


#: On-body LOS at 2.45 GHz [Reusens2009], unverified (module docstring).
ONBODY_LOS = PathLossModel(pl0_db=35.2, exponent=3.11, sigma_db=6.1, d0_m=0.10)

#: On-body NLOS (around the torso) at 2.45 GHz [Reusens2009], unverified.
ONBODY_NLOS = PathLossModel(pl0_db=48.4, exponent=5.9, sigma_db=5.0, d0_m=0.10)

#: Carrier frequency (Hz): the middle of the 2.4 GHz ISM band used by IEEE 802.15.4
#: (channels 11–26, 2405–2480 MHz) and the frequency of [Reusens2009].
FREQUENCY_HZ = 2.45e9

#: Loss (dB) of one body-worn antenna relative to free space: derived, half of the excess of
#: [Reusens2009]'s on-body PL0 at 10 cm (35.2 dB, two worn antennas) over free space at
#: 10 cm (20.2 dB at 2.45 GHz): (35.2 − 20.2) / 2 = 7.5 dB.
WORN_ANTENNA_LOSS_DB = 0.5 * (ONBODY_LOS.pl0_db - float(free_space_loss_db(0.10, FREQUENCY_HZ)))

#: Off-body (body-worn target to room anchor), indoor: exponent 1.7 and σ 1.2 dB
#: [IRACON2019], unverified; PL0 at 1 m = free space (40.2 dB, derived) + one worn antenna
#: (:data:`WORN_ANTENNA_LOSS_DB`, derived).
OFFBODY = PathLossModel(pl0_db=float(free_space_loss_db(1.0, FREQUENCY_HZ)) + WORN_ANTENNA_LOSS_DB, exponent=1.7,
                        sigma_db=1.2, d0_m=1.0)


@dataclass(frozen=True)
class RadioChannel:
    """Parameters of the simulated radio links (sources in the module docstring).

    Parameters
    ----------
    frequency_hz : float
        2.45e9 (:data:`FREQUENCY_HZ`).
    tx_power_dbm : float
        0 dBm: the CC2420's maximum output power [CC2420], *quoted*; we assume the SunSPOTs
        transmitted at full power.
    sensitivity_dbm : float
        −95 dBm [CC2420], *unverified*.  Packets whose received power is below it are lost.
    onbody_los, onbody_nlos : PathLossModel
        [Reusens2009] (:data:`ONBODY_LOS`, :data:`ONBODY_NLOS`), *unverified*.
    offbody : PathLossModel
        :data:`OFFBODY` ([IRACON2019] exponent and σ *unverified*; PL0 *derived*).
    creeping_db_per_cm : float
        2 dB per cm of creeping path around the body, *assumed* (the order of magnitude of
        creeping-wave attenuation around the torso at 2.45 GHz, cf. Chandra & Johansson
        2013; not checked).  With it a link through the torso or an arm reaches the caps.
    offbody_shadow_cap_db : float
        20 dB, *assumed*: the most the body can shadow a link to a room anchor, since wall
        and furniture reflections arrive around it (body-shadowing depths of 10–20 dB are
        typical of indoor off-body measurements; recalled, not checked).
    limb_shadow_cap_db : float
        10 dB, *assumed*: the most an arm or the neck adds to a link's shadowing.  A limb is
        less than a wavelength (12 cm) across, so the wave diffracts around it far more
        easily than around the torso; arm shadowing of on-body links is of the order of
        10 dB (recalled, not checked).
    onbody_room_path_loss_db : float
        78 dB, *derived from assumptions*: loss of the path from one worn antenna to another
        via a reflection in the room — free space over a 3 m path (49.8 dB at 2.45 GHz), two
        worn antennas (2 × 7.5 dB, :data:`WORN_ANTENNA_LOSS_DB`) and a 13 dB reflection
        (assumed).  Power-summed with the direct on-body path, it keeps a fully shadowed
        on-body link from falling off the NLOS fit's steep slope (n = 5.9, fitted on short
        links) beyond ~0.5 m.
    body_trim_m : float
        0.02 m: the first and last 2 cm of a link are not tested against the body (the nodes
        sit on the skin; *assumed*).
    antenna_peak_gain_dbi : float
        0 dBi, *assumed* (a small PCB antenna next to the body; a half-wave dipole would be
        2.15 dBi).
    antenna_floor_db : float
        −10 dB: depth of the pattern's nulls relative to the peak, *assumed* (body-worn
        antennas show filled-in nulls).
    shadow_length_m : float
        0.15 m: correlation length of the spatial shadowing field, *assumed* (changes of the
        body/multipath geometry over tens of cm; postures 11–40 cm apart get nearly
        independent offsets, movements vary smoothly).
    shadow_features : int
        64 random Fourier features per link for the field.
    day_decorrelation : float
        0.1: fraction of the spatial-field variance redrawn on another day, *assumed*.
    fading_k_db : float
        Rician K of off-body and shadowed links: 7 dB [EURASIP2014], *quoted*.
    fading_k_onbody_los_db : float
        20 dB for unshadowed on-body links, *assumed*: with the user still, a short on-body
        link is dominated by the wave along the skin; the room adds little.  It gives the
        nearly constant readings paper 002 observed ("some RSS PMFs … have almost zero
        variance", Sec. 5).  Shadowed on-body links move linearly (in dB) to ``fading_k_db``.
    coherence_time_s : float
        0.05 s: correlation time of the scattered component, *derived* from Clarke's
        ``T_c ≈ 0.423 / f_D`` with ``f_D = v / λ`` for people walking at v ≈ 1 m/s
        (λ = 12.2 cm → f_D ≈ 8 Hz → 52 ms); people moved in the room during paper 002's
        tests (Sec. 4.1).  The AR(1) coefficient per packet is ``exp(−Δt / T_c)``.
    slow_sigma_db, slow_time_s : float
        0.5 dB and 10 s: slow temporal shadowing per link (Gauss–Markov in dB), *assumed*.
    interference_fraction, interference_mean_burst, interference_loss_db :
        3 % of readings, in bursts of mean 10 packets (0.33 s), each burst −5 to −15 dB,
        *assumed* (people crossing links, Wi-Fi in the room: paper 002, Sec. 4.1).
    link_loss_rate, link_loss_mean_burst : float
        2 % of packets lost per link, bursts of mean 2 packets (Gilbert–Elliott), *assumed*.
    tx_loss_rate : float
        1 % of packets lost at every anchor at once (collision at the transmitter), *assumed*.
    tx_power_offset_db, rssi_offset_db : float
        Std (dB) of per-radio offsets: 1 dB per target's transmit power and 2 dB per
        anchor's RSSI, *assumed* (within the CC2420's ±6 dB RSSI accuracy, [CC2420]).
    rssi_noise_db : float
        0.25 dB rms read noise of the RSSI, *assumed* (the CC2420 averages its RSSI over
        8 symbols).
    rssi_max_dbm : float
        0 dBm: readings are clipped above (no effect at these distances).
    timing_jitter_s : float
        2 ms rms jitter of the packet times around the nominal rate, *assumed*.
    """

    frequency_hz: float = FREQUENCY_HZ
    tx_power_dbm: float = 0.0
    sensitivity_dbm: float = -95.0
    onbody_los: PathLossModel = ONBODY_LOS
    onbody_nlos: PathLossModel = ONBODY_NLOS
    offbody: PathLossModel = OFFBODY
    creeping_db_per_cm: float = 2.0
    offbody_shadow_cap_db: float = 20.0
    limb_shadow_cap_db: float = 10.0
    onbody_room_path_loss_db: float = 78.0
    body_trim_m: float = 0.02
    antenna_peak_gain_dbi: float = 0.0
    antenna_floor_db: float = -10.0
    shadow_length_m: float = 0.15
    shadow_features: int = 64
    day_decorrelation: float = 0.1
    fading_k_db: float = 7.0
    fading_k_onbody_los_db: float = 20.0
    coherence_time_s: float = 0.05
    slow_sigma_db: float = 0.5
    slow_time_s: float = 10.0
    interference_fraction: float = 0.03
    interference_mean_burst: float = 10.0
    interference_loss_db: tuple[float, float] = (5.0, 15.0)
    link_loss_rate: float = 0.02
    link_loss_mean_burst: float = 2.0
    tx_loss_rate: float = 0.01
    tx_power_offset_db: float = 1.0
    rssi_offset_db: float = 2.0
    rssi_noise_db: float = 0.25
    rssi_max_dbm: float = 0.0
    timing_jitter_s: float = 0.002

    def __post_init__(self):
        check_fields(self, positive=("frequency_hz", "shadow_length_m", "coherence_time_s", "slow_time_s",
                                     "interference_mean_burst", "link_loss_mean_burst"),
                     nonnegative=("creeping_db_per_cm", "offbody_shadow_cap_db", "limb_shadow_cap_db",
                                  "onbody_room_path_loss_db", "body_trim_m", "slow_sigma_db", "tx_power_offset_db",
                                  "rssi_offset_db", "rssi_noise_db", "timing_jitter_s"),
                     fractions=("interference_fraction", "link_loss_rate", "tx_loss_rate", "day_decorrelation"))
        if self.antenna_floor_db > 0.0:
            raise ValueError(f"antenna_floor_db must be <= 0 dB, got {self.antenna_floor_db!r}")
        lo, hi = (float(v) for v in self.interference_loss_db)
        if not 0.0 <= lo <= hi:
            raise ValueError(f"interference_loss_db must be (low, high) with 0 <= low <= high, got {(lo, hi)}")
        object.__setattr__(self, "interference_loss_db", (lo, hi))
        object.__setattr__(self, "shadow_features", check_count(self.shadow_features, "shadow_features"))
        for name in ("onbody_los", "onbody_nlos", "offbody"):
            check_type(getattr(self, name), PathLossModel, name)

    def ideal(self) -> RadioChannel:
        """The same channel without any randomness in time: no fading, slow shadowing,
        interference, random loss, jitter, radio offsets or read noise (spatial field kept)."""
        return dataclasses.replace(self, slow_sigma_db=0.0, interference_fraction=0.0, link_loss_rate=0.0,
                                   tx_loss_rate=0.0, tx_power_offset_db=0.0, rssi_offset_db=0.0, rssi_noise_db=0.0,
                                   timing_jitter_s=0.0, fading_k_db=np.inf, fading_k_onbody_los_db=np.inf)


# --------------------------------------------------------------------------------------------
# The link budget
# --------------------------------------------------------------------------------------------


#: Solids that shadow at most :attr:`RadioChannel.limb_shadow_cap_db`.
LIMB_SOLIDS = frozenset({"neck", "left_arm", "upper_arm", "forearm"})


def antenna_positions(kin: ArmKinematics, user: User, standoff_m: float = 0.01) -> np.ndarray:
    """Radio antenna position (2, T, 3) of T1 and T2 (m): on the lateral skin of their segment.

    The node sits on the segment's body −y side (lateral in the reference posture, arm
    forward), ``radius + standoff_m`` from the device point ``kin.pos`` on the arm axis
    (:mod:`wsnlib.sim.body`, "Body for shadowing").
    """
    check_type(kin, ArmKinematics, "kin")
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


def _shadow_field(anchors: np.ndarray, antenna: np.ndarray, target: int, user: User,
                  channel: RadioChannel) -> np.ndarray:
    """Unit-variance smooth random field X(anchor, antenna), (T, 7) (module docstring)."""
    m = channel.shadow_features
    x = np.concatenate([np.broadcast_to(anchors[None], antenna.shape[:1] + anchors.shape),
                        np.broadcast_to(antenna[:, None, :], antenna.shape[:1] + anchors.shape)], axis=-1)  # (T, 7, 6)
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
    check_type(kin, ArmKinematics, "kin")
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
            solid = dataclasses.replace(solid, base=solid.base[:, None, :], axis=solid.axis[:, None, :],
                                        ref=solid.ref[:, None, :])
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
    sigma = np.where(worn[None, :],
                     (1.0 - weight) * channel.onbody_los.sigma_db + weight * channel.onbody_nlos.sigma_db,
                     channel.offbody.sigma_db)
    shadow = sigma * _shadow_field(anchors, antenna, target, user, channel)
    peak, floor = channel.antenna_peak_gain_dbi, channel.antenna_floor_db
    gain_t = dipole_gain_db(link, axis[:, None, :], peak, floor)
    gain_a = dipole_gain_db(-link, user.anchor_axes[None, :, :], peak, floor)
    k_los, k_shadowed = channel.fading_k_onbody_los_db, channel.fading_k_db
    if np.isfinite(k_los) and np.isfinite(k_shadowed):
        k_onbody = k_los + weight * (k_shadowed - k_los)
    else:
        k_onbody = np.where(weight > 0.0, k_shadowed, k_los)
    k_db = np.where(worn[None, :], k_onbody, k_shadowed)
    mean_rx = channel.tx_power_dbm - total_loss + gain_t + gain_a + shadow
    return LinkBudget(distance_m=distance, chord_m=chord_trunk + chord_limb, nlos=(chord_trunk + chord_limb) > 0.0,
                      worn=worn, path_loss_db=path_loss, body_loss_db=body_loss, total_loss_db=total_loss,
                      nlos_weight=weight, gain_target_db=gain_t, gain_anchor_db=gain_a, shadow_sigma_db=sigma,
                      shadow_db=shadow, k_factor_db=np.broadcast_to(k_db, distance.shape).copy(), mean_rx_dbm=mean_rx)


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
    return ar1_filter(w, rho)


def ar1_filter(white: np.ndarray, rho: float, axis: int = -1) -> np.ndarray:
    """``x_k = ρ x_{k−1} + √(1−ρ²) w_k`` along ``axis`` from unit-variance white noise ``w``, started in
    the stationary distribution (``x_0 = w_0``), so every ``x_k`` has unit variance; ``ρ = 0`` gives ``w``."""
    from scipy.signal import lfilter  # here, not at the top: scipy.signal takes 0.5 s to import, in every kernel

    e = np.sqrt(1.0 - rho**2) * white
    first = (slice(None),) * (axis % white.ndim) + (0,)
    e[first] = white[first]
    return lfilter([1.0], [1.0, -rho], e, axis=axis)


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
        pieces.append(hold(q, hold_s, label=posture))
        q_prev = q
    return concatenate(pieces)


def static_session(user: User, *, rng: np.random.Generator, hold_s: float, session: str, transition_s: float = 3.0,
                   posture_jitter_deg: float = 2.0, packet_rate_hz: float = 30.0,
                   channel: RadioChannel | None = None) -> pd.DataFrame:
    """The user holds P1 … P5 for ``hold_s`` each, moving between them in ``transition_s``.

    Paper 002's training phase holds each posture 30 s (~1000 fingerprint vectors per target),
    session ``"training"``; its online phase, static part, holds them again on another day
    (``user.moved(rng)``), session ``"online_static"``.  Rows recorded while moving are
    labelled ``"transition"`` and dropped.  Each hold is the
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
    transition_s, posture_jitter_deg, packet_rate_hz, channel
        As above; ``channel`` default :class:`RadioChannel()`.

    Returns
    -------
    pandas.DataFrame
        See :func:`simulate_rss`; labels ``"P1"`` … ``"P5"``.
    """
    motion = _static_motion(rng, POSTURES, check_positive(hold_s, "hold_s"),
                            check_positive(transition_s, "transition_s"), posture_jitter_deg)
    df = simulate_rss(motion, user, rng=rng, packet_rate_hz=packet_rate_hz, channel=channel, session=session)
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
