"""Paper 002's posture study: from a simulated dynamic campaign to the errors of Sections 4.2 and 5.

The recursive estimate of target 2 (forearm) starts from the elbow estimated with target 1
(upper arm) — eq. (10), wired once in :func:`wsnlib.optimize.evaluate_chain` — so the two
targets' rows must be paired in time.  Each target node sends its own
packets (~30/s, not simultaneously), so for every target-2 vector of a movement we take the
latest target-1 vector of the same movement at or before it (causal: the base station has
that one when the target-2 packet arrives); target-2 vectors with no target-1 vector before
them in their movement are dropped.

Pitch is computed from each target's accelerometer stream as a whole (all labels, in time
order, at the packet rate), so that gating holds values across samples the way a running
system would, and then read at the paired rows.

Two checks of how far the Table 2–3 comparison can be trusted:

* :func:`with_reference_error`: score everything against a reference derived by hand as the
  paper's was (:func:`wsnlib.sim.optical.hand_derived_reference`), not against the truth;
* :func:`radio_sensitivity`: rerun a small Table 2 with the assumed radio-channel numbers of
  :class:`wsnlib.sim.radio.RadioChannel` perturbed (:data:`RADIO_ASSUMPTIONS`);
* :func:`kinect_sensitivity`: score the Kinect-like baseline again with its assumed per-joint
  bias and glitch rates (:mod:`wsnlib.sim.optical`, "not verified") moved over a grid.

:func:`joint_errors_cm` says where the estimated elbow and wrist sit against the true ones
(height against horizontal offset), :func:`user_pe_cm` averages errors per user as Table 3.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnlib._validation import check_count, check_nonnegative, check_rng, check_type
from wsnlib.io.rss import rss_vectors
from wsnlib.optimize import SearchData, SearchGrid, evaluate_chain, paper_tables
from wsnlib.posture import pitch_from_acc
from wsnlib.sim.campaign import simulate_dynamic_campaign
from wsnlib.sim.optical import (
    REFERENCE_ROTATION_STD_DEG,
    REFERENCE_TIMING_STD_S,
    hand_derived_reference,
    kinect_target_positions,
)
from wsnlib.sim.optical import kinect_errors as optical_kinect_errors
from wsnlib.sim.radio import RadioChannel

__all__ = ["KINECT_BIAS_STD_M", "KINECT_GLITCH_SCALES", "RADIO_ASSUMPTIONS", "RadioSensitivity", "StudyInputs",
           "joint_errors_cm", "kinect_crossing", "kinect_errors", "kinect_sensitivity", "perturbed_channel",
           "pitch_errors_deg", "radio_sensitivity", "selected_errors", "sensitivity_grid", "study_inputs",
           "true_joints_straight_arm", "user_pe_cm", "with_reference_error"]


@dataclass(frozen=True)
class StudyInputs:
    """Paired per-user inputs for :func:`wsnlib.optimize.paper_tables` and the Kinect baseline.

    Attributes
    ----------
    target1, target2 : dict[str, SearchData]
        Per user, rows paired in time (same count and movement per row).
    kinect : dict[str, numpy.ndarray]
        Per user, Kinect-estimated target positions ``(n, 2, 3)`` (m) at the same rows.
    time_s : dict[str, numpy.ndarray]
        Per user, time of each row (the target-2 packet, s).
    kinect_frame : dict[str, numpy.ndarray]
        Per user, ``(n, 2)`` index of the Kinect frame (of ``campaign.kinect_streams``) each
        row's Kinect position of T1 and T2 comes from.
    """

    target1: dict
    target2: dict
    kinect: dict
    time_s: dict
    kinect_frame: dict


def _pitch_stream(rows, method: str, fs: float, **options) -> np.ndarray:
    order = np.argsort(rows.time_s, kind="stable")
    pitch = np.empty(len(rows))
    pitch[order] = pitch_from_acc(rows.acc[order], method=method, fs=fs, **options)
    return pitch


def study_inputs(campaign, *, pitch_method: str = "gating", fs: float = 30.0, **pitch_options) -> StudyInputs:
    """Build paired :class:`~wsnlib.optimize.SearchData` for both targets of every user.

    Parameters
    ----------
    campaign : wsnlib.sim.campaign.DynamicCampaign
    pitch_method : str
        ``method`` of :func:`wsnlib.posture.pitch_from_acc` (``"gating"`` is the paper's).
    fs : float
        Rate of the accelerometer samples aligned to the packets (Hz).
    **pitch_options
        Passed to :func:`~wsnlib.posture.pitch_from_acc` (``xi``, ``cutoff_hz`` …).

    Returns
    -------
    StudyInputs
    """
    data = campaign.data
    training = rss_vectors(campaign.training_rss)
    chains = campaign.chains
    target1, target2, kinect, times, frames = {}, {}, {}, {}, {}
    frame_rate = campaign.kinect_model.frame_rate_hz
    for user in dict.fromkeys(data.user):
        rows = {t: data.select(user=user, target=t) for t in ("T1", "T2")}
        pitch = {t: _pitch_stream(r, pitch_method, fs, **pitch_options) for t, r in rows.items()}
        pick1, pick2 = [], []
        for movement in sorted(set(rows["T2"].movement[rows["T2"].movement > 0])):
            idx1 = np.flatnonzero(rows["T1"].movement == movement)
            idx2 = np.flatnonzero(rows["T2"].movement == movement)
            idx1 = idx1[np.argsort(rows["T1"].time_s[idx1], kind="stable")]
            idx2 = idx2[np.argsort(rows["T2"].time_s[idx2], kind="stable")]
            latest = np.searchsorted(rows["T1"].time_s[idx1], rows["T2"].time_s[idx2], side="right") - 1
            keep = latest >= 0
            pick1.append(idx1[latest[keep]])
            pick2.append(idx2[keep])
        pick1, pick2 = np.concatenate(pick1), np.concatenate(pick2)
        shared = {"movement": rows["T2"].movement[pick2], "chain": chains[user]}
        for key, target, pick, segment in (("T1", target1, pick1, 0), ("T2", target2, pick2, 1)):
            train = training.select(user=user, target=key)
            target[user] = SearchData(online_rss=rows[key].rss[pick], true_positions=rows[key].position[pick],
                                      pitch=pitch[key][pick], segment=segment, training_rss=train.rss,
                                      training_positions=train.position, **shared)
        kinect[user] = np.stack([rows["T1"].kinect[pick1], rows["T2"].kinect[pick2]], axis=1)
        frames[user] = np.rint(np.stack([rows["T1"].kinect_time_s[pick1], rows["T2"].kinect_time_s[pick2]], axis=1)
                               * frame_rate).astype(np.intp)
        times[user] = rows["T2"].time_s[pick2]
    return StudyInputs(target1=target1, target2=target2, kinect=kinect, time_s=times, kinect_frame=frames)


def selected_errors(inputs: StudyInputs, tables, *, approach: str, per_movement: bool) -> dict[str, np.ndarray]:
    """Per-sample position errors (cm) of the selected settings (Table 2 or 3), users pooled.

    Target 2 is evaluated from the elbow of target 1 under the same selection
    (:func:`wsnlib.optimize.evaluate_chain`), as in :func:`wsnlib.optimize.paper_tables`.

    Parameters
    ----------
    inputs : StudyInputs
    tables : wsnlib.optimize.PaperTables
    approach : {"deterministic", "probabilistic"}
    per_movement : bool
        True: Table 2's per-movement settings (Fig. 6(a)); False: Table 3's (Fig. 6(b)).

    Returns
    -------
    dict
        ``"T1"``, ``"T2"``: errors (cm) of every paired row of every user; ``"movement"``:
        the movement of each row; ``"user"``: its user (for intervals over users).
    """
    selection = tables.selection2 if per_movement else tables.selection3
    selection = selection[selection["approach"] == approach]
    pick = {t: selection[selection["target"] == n].drop(columns="target") for n, t in ((1, "T1"), (2, "T2"))}
    chains = {user: evaluate_chain(data1, inputs.target2[user], pick["T1"], pick["T2"])
              for user, data1 in inputs.target1.items()}
    return _pooled(inputs, {user: [100 * chain[t]["pe_m"] for t in ("T1", "T2")] for user, chain in chains.items()})


def kinect_errors(inputs: StudyInputs) -> dict[str, np.ndarray]:
    """Per-sample position errors (cm) of the Kinect-like baseline at the same rows, users pooled.

    Keys as :func:`selected_errors` (``"T1"``, ``"T2"``, ``"movement"``, ``"user"``); the errors
    are measured against ``true_positions`` of ``inputs`` (the hand-derived reference after
    :func:`with_reference_error`).
    """
    return _pooled(inputs, {user: [100 * np.linalg.norm(positions[:, index] - data[user].true_positions, axis=-1)
                                   for index, data in enumerate((inputs.target1, inputs.target2))]
                            for user, positions in inputs.kinect.items()})


def _pooled(inputs: StudyInputs, errors: dict) -> dict[str, np.ndarray]:
    """``errors`` (user → errors of T1 and T2 at the paired rows) pooled over users, with each row's
    movement and user: the dictionary of :func:`selected_errors`."""
    target1, target2 = zip(*errors.values(), strict=True)
    movement = [inputs.target1[user].movement for user in errors]
    users = [np.full(m.size, user, dtype=object) for user, m in zip(errors, movement, strict=True)]
    return {"T1": np.concatenate(target1), "T2": np.concatenate(target2), "movement": np.concatenate(movement),
            "user": np.concatenate(users)}


def user_pe_cm(errors: dict) -> pd.DataFrame:
    """Each user's PE (cm) per target as Table 3 averages: the mean over movements of each movement's mean.

    Parameters
    ----------
    errors : dict
        :func:`selected_errors` or :func:`kinect_errors` (``"T1"``, ``"T2"``, ``"movement"``,
        ``"user"``).

    Returns
    -------
    pandas.DataFrame
        Index ``user`` (sorted), columns ``T1``, ``T2``.
    """
    frame = pd.DataFrame(errors)
    return frame.groupby(["user", "movement"])[["T1", "T2"]].mean().groupby("user").mean()


#: The assumed Kinect numbers :func:`kinect_sensitivity` varies by default: the per-joint bias's
#: standard deviation per axis (m; nominal 0.02) and a factor on both glitch hazards (nominal 1).
KINECT_BIAS_STD_M = (0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.08)
KINECT_GLITCH_SCALES = (1.0, 2.0, 4.0)


def kinect_sensitivity(campaign, inputs: StudyInputs, *, bias_std_m=KINECT_BIAS_STD_M,
                       glitch_scales=KINECT_GLITCH_SCALES, n_draws: int = 10, seed: int = 0) -> pd.DataFrame:
    """The Kinect-like baseline's per-user PE when its assumed bias and glitch rate move.

    :mod:`wsnlib.sim.optical` marks the per-joint bias (``bias_std_m`` = 2 cm per axis) and the
    glitch hazards as assumed, not verified.  For every glitch scale ``g`` (both hazards of
    ``campaign.kinect_model`` times ``g``) and every bias ``b``, every user's Kinect is
    simulated again ``n_draws`` times on the campaign's true joints and camera
    (:func:`wsnlib.sim.optical.kinect_errors`, shoulder referencing as in the campaign:
    the tracked shoulder) and scored at the rows of ``inputs``, against their
    ``true_positions``, as :func:`kinect_errors` does.

    The draws of user ``u`` come from ``numpy.random.default_rng([seed, u])`` at every grid
    point (common random numbers: the draws' amounts depend only on the shapes), and the
    reported error is linear in the bias (``b`` times a unit-variance draw), so a bias grid
    costs one simulation per glitch scale and user.

    Parameters
    ----------
    campaign : wsnlib.sim.campaign.DynamicCampaign
        The campaign ``inputs`` were built from (:func:`study_inputs`).
    inputs : StudyInputs
    bias_std_m : sequence of float
        Per-axis standard deviations of the per-joint bias (m).
    glitch_scales : sequence of float
        Factors on ``glitch_rate_hz`` and ``glitch_rate_occluded_hz`` (0 switches glitches off).
    n_draws : int
        Kinect sessions simulated per user and grid point.
    seed : int

    Returns
    -------
    pandas.DataFrame
        Columns ``glitch_scale``, ``bias_std_m``, ``draw``, ``user``, ``T1``, ``T2`` (PE, cm, as
        :func:`user_pe_cm`) and ``pe_cm`` (their mean: Table 3's average of the two targets).
    """
    check_type(inputs, StudyInputs, "inputs")
    check_count(n_draws, "n_draws")
    biases = [check_nonnegative(b, "bias_std_m") for b in np.atleast_1d(bias_std_m)]
    scales = [check_nonnegative(g, "glitch_scales") for g in np.atleast_1d(glitch_scales)]
    base = campaign.kinect_model
    users = {user.name: (index, user) for index, user in enumerate(campaign.online_users)}
    missing = [user for user in inputs.target1 if user not in users]
    if missing:
        raise ValueError(f"users {missing} of inputs are not in the campaign")
    rows = []
    for scale in scales:
        model = dataclasses.replace(base, bias_std_m=1.0, glitch_rate_hz=base.glitch_rate_hz * scale,
                                    glitch_rate_occluded_hz=base.glitch_rate_occluded_hz * scale)
        for user, data1 in inputs.target1.items():
            index, person = users[user]
            stream = campaign.kinect_streams[index]
            truth = np.broadcast_to(stream.true_joints, (n_draws,) + stream.true_joints.shape)
            errors = optical_kinect_errors(truth, rng=np.random.default_rng([seed, index]), fs=model.frame_rate_hz,
                                           camera_position=stream.camera_position, camera_axis=stream.camera_axis,
                                           model=model)
            d1, d2 = person.target_distances_m
            fractions = (d1 / person.upper_arm_m, (d2 - person.upper_arm_m) / person.forearm_m)
            frames = inputs.kinect_frame[user]
            true = np.stack([data1.true_positions, inputs.target2[user].true_positions], axis=1)   # (n, 2, 3)
            # Table 3's averaging (user_pe_cm): each movement's mean, then the mean over movements.
            _, movement = np.unique(data1.movement, return_inverse=True)
            weights = np.eye(movement.max() + 1)[movement]                           # (n, M)
            weights = weights / weights.sum(axis=0) / weights.shape[1]
            for bias in biases:
                error = bias * errors.bias + errors.jitter + errors.glitch
                joints = errors.truth + (error - error[..., :1, :])            # referenced to the tracked shoulder
                targets = kinect_target_positions(joints, fractions=fractions)   # (draws, K, 2, 3)
                reported = np.stack([targets[:, frames[:, t], t] for t in (0, 1)], axis=2)  # (draws, n, 2, 3)
                pe = 100 * np.linalg.norm(reported - true, axis=-1)             # (draws, n, 2) cm
                pe = np.einsum("dnt,nm->dt", pe, weights)                       # (draws, 2)
                rows.append(pd.DataFrame({"glitch_scale": scale, "bias_std_m": bias, "draw": np.arange(n_draws),
                                          "user": user, "T1": pe[:, 0], "T2": pe[:, 1]}))
    out = pd.concat(rows, ignore_index=True)
    out["pe_cm"] = out[["T1", "T2"]].mean(axis=1)
    return out


def kinect_crossing(sweep: pd.DataFrame, level_cm: float) -> pd.Series:
    """Per glitch scale, the bias at which the Kinect-like baseline's mean PE reaches ``level_cm``.

    Parameters
    ----------
    sweep : DataFrame
        :func:`kinect_sensitivity`'s output.
    level_cm : float
        E.g. the deterministic approach's mean PE over users (cm).

    Returns
    -------
    pandas.Series
        Index ``glitch_scale``; the per-axis bias (m), linear between the grid's biases, at
        which the mean over draws of the users' mean PE first reaches ``level_cm``: the
        smallest bias of the grid if it does there already (smaller ones are not searched),
        NaN if it does nowhere in the grid.
    """
    curve = sweep.groupby(["glitch_scale", "bias_std_m", "draw"])["pe_cm"].mean().groupby(
        ["glitch_scale", "bias_std_m"]).mean()
    out = {}
    for scale, values in curve.groupby(level="glitch_scale"):
        bias = values.index.get_level_values("bias_std_m").to_numpy()
        pe = values.to_numpy()
        above = np.flatnonzero(pe >= level_cm)
        if above.size == 0:
            out[scale] = np.nan
        elif above[0] == 0:
            out[scale] = float(bias[0])
        else:
            i = above[0]
            out[scale] = float(bias[i - 1] + (level_cm - pe[i - 1]) * (bias[i] - bias[i - 1]) / (pe[i] - pe[i - 1]))
    return pd.Series(out, name="bias_std_m").rename_axis("glitch_scale")


def pitch_errors_deg(data, *, method: str, fs: float = 30.0, **options):
    """Accelerometer pitch minus true pitch (°) for every aligned row of a dynamic campaign.

    Pitch is computed per (user, target) stream in time order, as in :func:`study_inputs`.

    Returns
    -------
    pandas.DataFrame
        Columns ``user``, ``target``, ``movement`` (0 outside movements), ``label``,
        ``error_deg``.
    """
    frames = []
    for user in dict.fromkeys(data.user):
        for target in ("T1", "T2"):
            rows = data.select(user=user, target=target)
            error = np.degrees(_pitch_stream(rows, method, fs, **options) - rows.pitch_true_rad)
            frames.append(pd.DataFrame({"user": user, "target": target, "movement": rows.movement,
                                        "label": rows.label, "error_deg": error}))
    return pd.concat(frames, ignore_index=True)


def true_joints_straight_arm(inputs: StudyInputs, user: str) -> dict[str, np.ndarray]:
    """True elbow and wrist (m) at the paired rows, for a straight arm (all of paper 002's movements).

    With the elbow extended, both targets lie on the line from the shoulder, so the elbow is
    the target-1 direction at the upper-arm length and the wrist the same direction at the
    whole arm's length.
    """
    data1 = inputs.target1[user]
    lengths = data1.chain.segment_lengths_m
    direction = data1.true_positions / np.linalg.norm(data1.true_positions, axis=1, keepdims=True)
    return {"elbow": direction * lengths[0], "wrist": direction * (lengths[0] + lengths[1])}


def joint_errors_cm(inputs: StudyInputs, chains: dict) -> pd.DataFrame:
    """How far the estimated elbow and wrist are from the true ones, and in which direction.

    Parameters
    ----------
    inputs : StudyInputs
    chains : dict
        Per user, :func:`wsnlib.optimize.evaluate_chain`'s output for that user's rows
        (``"T1"["joints"]`` the elbow, ``"T2"["joints"]`` the wrist).

    Returns
    -------
    pandas.DataFrame
        One row per user, paired row and joint: ``user``, ``movement``, ``joint`` (``"elbow"``,
        ``"wrist"``), ``error_cm`` (distance to the true joint of the straight arm,
        :func:`true_joints_straight_arm`), ``vertical_cm`` (|Δz|: height, which the
        accelerometer's pitch sets) and ``horizontal_cm`` (the horizontal distance, which the
        radio heading sets), all in cm.
    """
    frames = []
    for user, chain in chains.items():
        truth = true_joints_straight_arm(inputs, user)
        for joint, target in (("elbow", "T1"), ("wrist", "T2")):
            delta = 100 * (np.asarray(chain[target]["joints"]) - truth[joint])
            frames.append(pd.DataFrame({"user": user, "movement": inputs.target1[user].movement, "joint": joint,
                                        "error_cm": np.linalg.norm(delta, axis=1), "vertical_cm": np.abs(delta[:, 2]),
                                        "horizontal_cm": np.hypot(delta[:, 0], delta[:, 1])}))
    return pd.concat(frames, ignore_index=True)


def with_reference_error(inputs: StudyInputs, *, rng: np.random.Generator,
                         rotation_std_deg: float = REFERENCE_ROTATION_STD_DEG,
                         timing_std_s: float = REFERENCE_TIMING_STD_S) -> StudyInputs:
    """The same inputs scored against a hand-derived reference, as paper 002 was (Sec. 4.2).

    Every user's ``true_positions`` of both targets are replaced by
    :func:`wsnlib.sim.optical.hand_derived_reference` (one posture rotation and one timing
    offset per movement, shared by the two targets of a row); the RSS, pitch, Kinect
    positions and fitted estimators are unchanged.  :func:`wsnlib.optimize.paper_tables`,
    :func:`selected_errors` and :func:`kinect_errors` on the result then measure every system —
    ours and the Kinect alike — against that reference, as the paper did.

    Parameters
    ----------
    inputs : StudyInputs
    rng : numpy.random.Generator
        Drawn user by user, in ``inputs`` order.
    rotation_std_deg, timing_std_s : float
        As in :func:`~wsnlib.sim.optical.hand_derived_reference` (defaults: 3°, 0.1 s, assumed).

    Returns
    -------
    StudyInputs
    """
    check_type(inputs, StudyInputs, "inputs")
    target1, target2 = {}, {}
    for user, data1 in inputs.target1.items():
        data2 = inputs.target2[user]
        truth = np.stack([data1.true_positions, data2.true_positions], axis=1)
        reference = hand_derived_reference(truth, data1.movement, inputs.time_s[user], rng=rng,
                                           rotation_std_deg=rotation_std_deg, timing_std_s=timing_std_s)
        target1[user] = dataclasses.replace(data1, true_positions=reference[:, 0])
        target2[user] = dataclasses.replace(data2, true_positions=reference[:, 1])
    return dataclasses.replace(inputs, target1=target1, target2=target2)


# --- Sensitivity of Table 2 to the assumed radio numbers -------------------------------------

#: The radio-channel numbers marked *assumed* or *unverified* in :mod:`wsnlib.sim.radio`, with the
#: half-width of their perturbation: ``(field, half_width, kind)``; ``"relative"`` draws
#: ``value · (1 + h·u)``, ``"additive"`` draws ``value + h·u``, ``u ~ U[−1, 1]`` times ``spread``.
#: A dotted field is a field of a :class:`~wsnlib.sim.radio.PathLossModel`.  The ranges are
#: ours: ±50 % for assumed scales and caps, ±100 % (down to 0, up to double) for assumed rates,
#: offsets and noise, ±20–30 % for the unverified path-loss fits, a few dB for assumed levels.
RADIO_ASSUMPTIONS = (
    ("sensitivity_dbm", 3.0, "additive"),
    ("onbody_los.exponent", 0.2, "relative"),
    ("onbody_los.sigma_db", 0.3, "relative"),
    ("onbody_nlos.exponent", 0.2, "relative"),
    ("onbody_nlos.sigma_db", 0.3, "relative"),
    ("offbody.exponent", 0.2, "relative"),
    ("offbody.sigma_db", 0.3, "relative"),
    ("creeping_db_per_cm", 0.5, "relative"),
    ("offbody_shadow_cap_db", 0.5, "relative"),
    ("limb_shadow_cap_db", 0.5, "relative"),
    ("onbody_room_path_loss_db", 6.0, "additive"),
    ("body_trim_m", 0.5, "relative"),
    ("antenna_peak_gain_dbi", 2.0, "additive"),
    ("antenna_floor_db", 5.0, "additive"),
    ("shadow_length_m", 0.5, "relative"),
    ("day_decorrelation", 1.0, "relative"),
    ("fading_k_onbody_los_db", 6.0, "additive"),
    ("slow_sigma_db", 1.0, "relative"),
    ("slow_time_s", 0.5, "relative"),
    ("interference_fraction", 1.0, "relative"),
    ("interference_mean_burst", 0.5, "relative"),
    ("link_loss_rate", 1.0, "relative"),
    ("link_loss_mean_burst", 0.5, "relative"),
    ("tx_loss_rate", 1.0, "relative"),
    ("tx_power_offset_db", 1.0, "relative"),
    ("rssi_offset_db", 1.0, "relative"),
    ("rssi_noise_db", 1.0, "relative"),
    ("timing_jitter_s", 1.0, "relative"),
)

_FRACTIONS = {"day_decorrelation", "interference_fraction", "link_loss_rate", "tx_loss_rate"}


def perturbed_channel(factors: dict, channel=None):
    """A :class:`~wsnlib.sim.radio.RadioChannel` with :data:`RADIO_ASSUMPTIONS` perturbed.

    Parameters
    ----------
    factors : dict
        ``field → s`` with ``s ∈ [−1, 1]`` (already multiplied by the spread): the field becomes
        ``value · (1 + h·s)`` or ``value + h·s`` (see :data:`RADIO_ASSUMPTIONS`).  Fields not
        given keep their value.  Fractions are clipped to [0, 1], the antenna floor to ≤ 0 dB.
    channel : RadioChannel, optional
        The nominal channel; default ``RadioChannel()``.
    """
    channel = RadioChannel() if channel is None else channel
    known = {name: (half, kind) for name, half, kind in RADIO_ASSUMPTIONS}
    unknown = sorted(set(factors) - set(known))
    if unknown:
        raise ValueError(f"factors names unknown fields {unknown}; see RADIO_ASSUMPTIONS")
    top: dict = {}
    nested: dict = {}
    for name, s in factors.items():
        s = float(s)
        if not -1.0 - 1e-12 <= s <= 1.0 + 1e-12:
            raise ValueError(f"factor of {name} must lie in [-1, 1], got {s}")
        half, kind = known[name]
        owner, _, field = name.rpartition(".")
        base = getattr(getattr(channel, owner), field) if owner else getattr(channel, name)
        value = base * (1.0 + half * s) if kind == "relative" else base + half * s
        if name in _FRACTIONS:
            value = min(max(value, 0.0), 1.0)
        if name == "antenna_floor_db":
            value = min(value, 0.0)
        if owner:
            nested.setdefault(owner, {})[field] = value
        else:
            top[name] = value
    for owner, changes in nested.items():
        top[owner] = dataclasses.replace(getattr(channel, owner), **changes)
    return dataclasses.replace(channel, **top)


@dataclass(frozen=True)
class RadioSensitivity:
    """What :func:`radio_sensitivity` returns.

    Attributes
    ----------
    factors : pandas.DataFrame
        One row per draw (index ``draw``; draw 0 is the nominal channel), one
        column per :data:`RADIO_ASSUMPTIONS` field: the factor ``s ∈ [−spread, spread]``.
    pe : pandas.DataFrame
        Table 2's PE (cm) per draw: columns ``draw``, ``target``, ``movement``, ``approach``,
        ``pe_cm``.
    summary : pandas.DataFrame
        Index ``(target, movement, approach)``; columns ``nominal_cm`` (draw 0), and with
        perturbed draws ``min_cm``, ``median_cm``, ``max_cm`` and ``range_cm`` over them (draw
        0 excluded).
    """

    factors: object
    pe: object
    summary: object


def sensitivity_grid():
    """The small search grid of :func:`radio_sensitivity`: every subset, both distances, k ∈ {1, 3}, p_s = 2."""
    return SearchGrid(knn_neighbors=(1, 3), powers=(2,), pknn_neighbors=(1, 3))


def radio_sensitivity(*, rng: np.random.Generator, n_draws: int = 8, spread: float = 1.0, campaign_seed: int = 2023,
                      n_users: int = 2, hold_s: float = 8.0, grid=None,
                      quick: bool = False, pitch_method: str = "gating", **pitch_options) -> RadioSensitivity:
    """Spread of Table 2's per-movement PE when the assumed radio numbers move within their ranges.

    For each draw, every field of :data:`RADIO_ASSUMPTIONS` gets a factor ``spread·u``,
    ``u ~ U[−1, 1]`` from ``rng``; the campaign is simulated with that channel
    (:func:`wsnlib.sim.campaign.simulate_dynamic_campaign`, always from
    ``default_rng(campaign_seed)``: the same users, motions and noise draws, so that draws
    differ by the channel numbers, as far as the simulator's draws do not depend on them),
    turned into :func:`study_inputs` and searched with a small grid
    (:func:`sensitivity_grid`) by :func:`wsnlib.optimize.paper_tables`.  Users, hold times
    and the grid are smaller than the paper's, so read the spread relative to the nominal
    run of the same size, not against Table 2 itself.

    Parameters
    ----------
    rng : numpy.random.Generator
        Draws the factors.
    n_draws : int
        Perturbed channels (the nominal one comes in addition).
    spread : float
        Multiplies every half-width (1 = the ranges of :data:`RADIO_ASSUMPTIONS`; 0 = none).
    campaign_seed : int
    n_users, hold_s : int, float
        Size of each simulated campaign.
    grid : SearchGrid, optional
        Default :func:`sensitivity_grid`.
    quick : bool
        A few seconds' version: 2 draws, 1 user, 4 s holds (overrides those arguments).
    pitch_method, **pitch_options
        As in :func:`study_inputs`.

    Returns
    -------
    RadioSensitivity
    """
    check_rng(rng)
    if quick:
        n_draws, n_users, hold_s = 2, 1, 4.0
    check_count(n_draws, "n_draws", 0)
    spread = float(spread)
    if not 0.0 <= spread <= 1.0:
        raise ValueError(f"spread must lie in [0, 1], got {spread!r}")
    grid = sensitivity_grid() if grid is None else grid
    names = [name for name, _, _ in RADIO_ASSUMPTIONS]
    draws = np.vstack([np.zeros((1, len(names))), spread * rng.uniform(-1.0, 1.0, size=(n_draws, len(names)))])
    factors = pd.DataFrame(draws, columns=names, index=pd.RangeIndex(0, draws.shape[0], name="draw"))
    frames = []
    for draw, row in factors.iterrows():
        channel = perturbed_channel(row.to_dict())
        campaign = simulate_dynamic_campaign(n_users, rng=np.random.default_rng(campaign_seed), hold_s=hold_s,
                                             channel=channel)
        inputs = study_inputs(campaign, pitch_method=pitch_method, **pitch_options)
        tables = paper_tables(inputs.target1, inputs.target2, grid=grid)
        frames.append(tables.selection2[["target", "movement", "approach", "pe_cm"]].assign(draw=draw))
    pe = pd.concat(frames, ignore_index=True)[["draw", "target", "movement", "approach", "pe_cm"]]
    keys = ["target", "movement", "approach"]
    wide = pe.pivot_table(index=keys, columns="draw", values="pe_cm")
    perturbed = wide.drop(columns=0)
    summary = pd.DataFrame({"nominal_cm": wide[0]}, index=wide.index)
    if n_draws:
        summary = summary.join(perturbed.agg(["min", "median", "max"], axis=1).add_suffix("_cm"))
        summary["range_cm"] = summary["max_cm"] - summary["min_cm"]
    return RadioSensitivity(factors=factors, pe=pe, summary=summary)
