"""From a simulated dynamic campaign to the inputs of paper 002's evaluation (Sections 4.2, 5).

The recursive estimate of target 2 (forearm) starts from the elbow estimated with target 1
(upper arm), so the two targets' rows must be paired in time.  Each target node sends its own
packets (~30/s, not simultaneously), so for every target-2 vector of a movement we take the
latest target-1 vector of the same movement at or before it (causal: the base station has
that one when the target-2 packet arrives); target-2 vectors with no target-1 vector before
them in their movement are dropped.

Pitch is computed from each target's accelerometer stream as a whole (all labels, in time
order, at the packet rate), so that gating holds values across samples the way a running
system would, and then read at the paired rows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wsnlib.optimize import SearchData
from wsnlib.posture import pitch_from_acc
from wsnlib.rss import rss_vectors


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
    """

    target1: dict
    target2: dict
    kinect: dict
    time_s: dict


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
    target1, target2, kinect, times = {}, {}, {}, {}
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
        times[user] = rows["T2"].time_s[pick2]
    return StudyInputs(target1=target1, target2=target2, kinect=kinect, time_s=times)


def selected_errors(inputs: StudyInputs, tables, *, approach: str, per_movement: bool) -> dict[str, np.ndarray]:
    """Per-sample position errors (cm) of the selected settings (Table 2 or 3), users pooled.

    Target 2 is evaluated with the elbow of target 1 under the same selection, as in
    :func:`wsnlib.optimize.paper_tables`.

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
        the movement of each row.
    """
    from wsnlib.optimize import evaluate_selection

    selection = tables.selection2 if per_movement else tables.selection3
    selection = selection[selection["approach"] == approach]
    pick = {t: selection[selection["target"] == n].drop(columns="target") for n, t in ((1, "T1"), (2, "T2"))}
    errors = {"T1": [], "T2": [], "movement": []}
    for user, data1 in inputs.target1.items():
        first = evaluate_selection(data1, pick["T1"])
        second = evaluate_selection(inputs.target2[user].with_proximal(first["joints"]), pick["T2"])
        errors["T1"].append(100 * first["pe_m"])
        errors["T2"].append(100 * second["pe_m"])
        errors["movement"].append(data1.movement)
    return {key: np.concatenate(values) for key, values in errors.items()}


def kinect_errors(inputs: StudyInputs) -> dict[str, np.ndarray]:
    """Per-sample position errors (cm) of the Kinect-like baseline at the same rows, users pooled."""
    errors = {"T1": [], "T2": [], "movement": []}
    for user, positions in inputs.kinect.items():
        for index, target in enumerate(("T1", "T2")):
            truth = (inputs.target1 if index == 0 else inputs.target2)[user].true_positions
            errors[target].append(100 * np.linalg.norm(positions[:, index] - truth, axis=-1))
        errors["movement"].append(inputs.target1[user].movement)
    return {key: np.concatenate(values) for key, values in errors.items()}


def pitch_errors_deg(data, *, method: str, fs: float = 30.0, **options):
    """Accelerometer pitch minus true pitch (°) for every aligned row of a dynamic campaign.

    Pitch is computed per (user, target) stream in time order, as in :func:`study_inputs`.

    Returns
    -------
    pandas.DataFrame
        Columns ``user``, ``target``, ``movement`` (0 outside movements), ``label``,
        ``error_deg``.
    """
    import pandas as pd

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
