"""A whole measurement campaign of paper 002 (Sec. 4.1), simulated: users × sessions.

For each of ``n_users`` simulated users (:func:`wsnlib.sim.body.make_users`): a training
session (five postures held ``hold_s`` each), then, on a different "day" (re-donned t-shirt,
moved anchors, new fading: :meth:`wsnlib.sim.body.User.moved`), an online static session
(the five postures again) and an online dynamic session (the four transitional movements,
twice).  All from one seeded generator, in a fixed order, so a seed fixes the campaign.

:func:`simulate_campaign` gives the RSS tables only.  :func:`simulate_dynamic_campaign` gives,
for the online dynamic session, everything paper 002's Sec. 5.2 compares, on one clock: the
RSS packets, each target's 30 Hz accelerometer stream (:mod:`wsnlib.sim.sunspot`), the
Kinect's estimate of the target positions (:mod:`wsnlib.sim.optical`) and the ground truth,
plus :class:`DynamicData`, the same aligned per RSS vector.

The Kinect's view of one user is :func:`simulate_kinect_stream` (camera placement, frames at
30 fps, reported joints, the target positions derived from them); the long accelerometer and
Kinect tables are :func:`sample_table`.  :func:`dynamic_campaign`
memoises the notebooks' campaign; :func:`write_dynamic_campaign` and
:func:`read_dynamic_campaign` write and read its files, and real logs converted to the same
files give the same :class:`DynamicData`.

Clock and alignment (:func:`align_dynamic`)
-------------------------------------------
Time 0 is the start of the session for every stream.  RSS packets of T1 leave at about
``k/30`` s and those of T2 half a period later (:func:`wsnlib.sim.radio.packet_times`, with
jitter); the accelerometer samples are stamped ``k/30`` s (the end of the 1/30 s window they
average) and the Kinect frames ``k/30`` s.  Each RSS vector (one per packet and target,
``rss_vectors(window_packets=1, fill="last")``) is paired with the **latest** accelerometer
sample and the latest Kinect frame at or before its time stamp, never a later one: what an
online system has when the packet arrives.  All time stamps are rounded to 1 µs, so the
pairing is the same after a CSV round trip.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from wsnlib._validation import check_count, check_type
from wsnlib.io import accel
from wsnlib.io import rss as rss_format
from wsnlib.io.vectors import select_rows
from wsnlib.posture import ArmChain
from wsnlib.sim.arm_motion import ArmMotion
from wsnlib.sim.body import User, make_users
from wsnlib.sim.optical import PAPER_CAMERA_DISTANCE_M, KinectModel, kinect_target_positions, simulate_kinect
from wsnlib.sim.radio import (
    RadioChannel,
    concat_rss,
    online_dynamic_motion,
    online_dynamic_session,
    simulate_rss,
    static_session,
)
from wsnlib.sim.sunspot import SunspotAcc, SunspotAccSpec, output_times, simulate_sunspot_acc
from wsnlib.testbed import TARGET_NAMES


@dataclass(frozen=True)
class Campaign:
    """Simulated RSS campaign.

    Attributes
    ----------
    rss : pandas.DataFrame
        Long RSS table (schema of :mod:`wsnlib.io.rss`), every user and session.
    users : tuple of User
        The users as trained (day 1).
    online_users : tuple of User
        The same users on the online day (moved anchors).
    """

    rss: pd.DataFrame
    users: tuple[User, ...]
    online_users: tuple[User, ...]


def simulate_campaign(n_users: int = 5, *, rng: np.random.Generator, hold_s: float = 30.0,
                      static_hold_s: float = 10.0, dynamic: bool = True) -> Campaign:
    """Simulate training, online static and (optionally) online dynamic sessions for every user.

    Parameters
    ----------
    n_users : int
        Number of users (paper 002: five).
    rng : numpy.random.Generator
    hold_s : float
        Seconds each posture is held in training (paper: about 30 s, ~1000 vectors per target).
    static_hold_s : float
        Seconds each posture is held in the online static session (not given in the paper;
        assumed).
    dynamic : bool
        Also simulate the online dynamic session (8 movements).

    Returns
    -------
    Campaign
    """
    users = make_users(check_count(n_users, "n_users"), rng=rng)
    frames, online_users = [], []
    for user in users:
        frames.append(static_session(user, rng=rng, hold_s=hold_s, session="training"))
        day2 = user.moved(rng)
        online_users.append(day2)
        frames.append(static_session(day2, rng=rng, hold_s=static_hold_s, session="online_static"))
        if dynamic:
            frames.append(online_dynamic_session(day2, rng=rng))
    return Campaign(rss=concat_rss(frames), users=tuple(users), online_users=tuple(online_users))


# --------------------------------------------------------------------------------------------
# The Kinect's view of one user in one session
# --------------------------------------------------------------------------------------------


#: Height of the Kinect relative to the shoulder for a 1.75 m user (m): chest height, the
#: level of the left chest pocket (A1) in :mod:`wsnlib.sim.body`; scaled with the user's height.
CAMERA_HEIGHT_175_M = -0.15


def kinect_camera(user: User, distance_m: float = PAPER_CAMERA_DISTANCE_M) -> tuple[np.ndarray, np.ndarray]:
    """Kinect position (3,) and viewing direction (3,) in ``user``'s shoulder frame.

    ``distance_m`` in front of the user (paper 002: "at a distance of about 3 m"), facing the
    user (looking along −y), centred on the torso (x = the torso centre, 19 cm left of the right
    shoulder for a 1.75 m user), at chest height (:data:`CAMERA_HEIGHT_175_M`, scaled).  The
    height and centring are *assumed*; the paper gives only the distance.
    """
    scale = user.height_m / 1.75
    position = np.array([user.body.torso_center_x_m, float(distance_m), CAMERA_HEIGHT_175_M * scale])
    return position, np.array([0.0, -1.0, 0.0])


@dataclass(frozen=True, eq=False)
class KinectStream:
    """What the simulated Kinect reported during one session (shapes with ``K`` frames).

    Attributes
    ----------
    time_s : (K,)
        Frame times (s), ``k / frame_rate_hz`` from 0, rounded to 1 µs.
    joints : (K, 3, 3)
        Reported shoulder, elbow, wrist (m, shoulder frame; referenced to the tracked shoulder
        unless ``relative_to`` said otherwise).
    targets : (K, 2, 3)
        Target positions derived from the reported joints at each target's fraction along its
        segment (:func:`wsnlib.sim.optical.kinect_target_positions`), m.
    true_joints : (K, 3, 3)
        The true joints at the frame times (m).
    true_targets : (K, 2, 3)
        The true target positions on the arm axis (m).
    label : (K,) object
        Label of the motion piece at each frame.
    camera_position, camera_axis : (3,)
        Camera placement (:func:`kinect_camera`).
    """

    time_s: np.ndarray
    joints: np.ndarray
    targets: np.ndarray
    true_joints: np.ndarray
    true_targets: np.ndarray
    label: np.ndarray
    camera_position: np.ndarray
    camera_axis: np.ndarray


def simulate_kinect_stream(motion: ArmMotion, user: User, *, rng: np.random.Generator, model: KinectModel | None = None,
                           camera_distance_m: float = PAPER_CAMERA_DISTANCE_M, relative_to: str = "tracked_shoulder",
                           duration_s: float | None = None) -> KinectStream:
    """The Kinect's view of ``motion``: true joints at 30 fps → :func:`simulate_kinect` → targets.

    Frames at ``k / frame_rate_hz`` for ``k = 0 … ⌊duration · rate⌋``; camera from
    :func:`kinect_camera`; T1 at ``d1 / upper_arm`` along shoulder → elbow and T2 at
    ``(d2 − upper_arm) / forearm`` along elbow → wrist (the user's true strap positions, which
    paper 002's experimenters knew).  ``rng`` draws the Kinect errors only.
    """
    model = KinectModel() if model is None else model
    duration = motion.total_duration_s if duration_s is None else float(duration_s)
    times = output_times(duration, model.frame_rate_hz)
    kin = motion.kinematics(times, user)
    upper, fore = user.upper_arm_m, user.forearm_m
    true_joints = np.moveaxis(kin.joint_pos, 0, 1)  # (K, 3, 3)
    position, axis = kinect_camera(user, camera_distance_m)
    joints = simulate_kinect(true_joints, rng=rng, fs=model.frame_rate_hz, camera_position=position, camera_axis=axis,
                             model=model, relative_to=relative_to)
    d1, d2 = user.target_distances_m
    fractions = (d1 / upper, (d2 - upper) / fore)
    return KinectStream(time_s=times, joints=joints, targets=kinect_target_positions(joints, fractions=fractions),
                        true_joints=true_joints, true_targets=np.moveaxis(kin.pos, 0, 1).copy(), label=kin.label,
                        camera_position=position, camera_axis=axis)


# --------------------------------------------------------------------------------------------
# The online dynamic session on one clock: sample tables and alignment
# --------------------------------------------------------------------------------------------


#: Session name of the online dynamic session (as :func:`wsnlib.sim.radio.online_dynamic_session`).
DYNAMIC_SESSION = "online_dynamic"

_MOVEMENT_RE = re.compile(r"^M(\d+)_")


def sample_table(kind: str, streams, users, rate_hz: float) -> pd.DataFrame:
    """Long sample table (:mod:`wsnlib.io.accel`) of the dynamic session, every user in order.

    ``kind`` ``"acc"``: the accelerometer readings of :class:`SunspotAcc` streams; ``"kinect"``:
    the target positions of :class:`KinectStream` streams.  ``streams[i]`` is the stream of
    ``users[i]``.  Values rounded to 6 decimals (the CSV precision), rows ordered by user, time,
    then target; ``attrs["rate_hz"]`` = ``rate_hz``.
    """
    frames = []
    for stream, user in zip(streams, users, strict=True):
        values = stream.acc if kind == "acc" else stream.targets
        n, n_targets = values.shape[:2]
        flat = values.reshape(n * n_targets, 3)
        table = {"time_s": np.repeat(stream.time_s, n_targets), "user": user.name, "session": DYNAMIC_SESSION,
                 "target": np.tile(np.asarray(TARGET_NAMES[:n_targets], dtype=object), n),
                 "label": np.repeat(np.asarray(stream.label, dtype=object), n_targets)}
        for j, column in enumerate(accel.VALUE_COLUMNS[kind]):
            table[column] = np.round(flat[:, j], 6) + 0.0  # the CSV precision, so memory and file agree
        frames.append(pd.DataFrame(table).astype({"user": object, "session": object, "target": object,
                                                  "label": object}))
    out = pd.concat(frames, ignore_index=True)
    out.attrs = {"rate_hz": float(rate_hz)}
    return out


@dataclass(frozen=True, eq=False)
class DynamicData:
    """RSS vectors of the online dynamic session with everything else aligned to them.

    One row per RSS vector: per packet of a target (``rss_vectors(window_packets=1,
    fill="last")``), concatenated over users in order, then target, then time.  ``n`` rows.

    Attributes
    ----------
    user, target : (n,) object
        User name; target name ("T1" upper arm, "T2" forearm).
    target_index : (n,) int
        0 for T1, 1 for T2 (the segment index in :class:`wsnlib.posture.ArmChain`).
    time_s : (n,)
        Packet time stamp (s, session clock).
    rss : (n, N_anchors)
        RSS (dBm), anchors in :attr:`anchors` order; missing readings carried forward, −95 dBm
        before the first.
    label : (n,) object
        Label of the packet (posture, "M1_lower_P2_P3_P1" … or "transition").
    movement : (n,) int
        Movement number 1 … 8 while a movement is under way (from the label), 0 otherwise.
    position : (n, 3)
        True target position at the packet time (m, shoulder frame, on the arm axis).
    pitch_true_rad : (n,)
        True pitch of the target's segment: the elevation of ``position`` seen from the
        shoulder, ``asin(z / |p|)`` (exact for the straight arm of :mod:`wsnlib.sim.body`).
    acc : (n, 3)
        The latest accelerometer sample at or before ``time_s`` (m/s², device frame).
    acc_time_s : (n,)
        Its time stamp (s); ``acc_time_s <= time_s`` always.
    kinect : (n, 3)
        The latest Kinect estimate of the target at or before ``time_s`` (m, shoulder frame).
    kinect_time_s : (n,)
        Its frame time (s).
    segment_length_m : (n,)
        Length of the target's segment (m): upper arm for T1, forearm for T2 (the paper's d).
    device_offset_m : (n,)
        Distance of the target from its segment's proximal joint (m): from the shoulder for T1,
        from the elbow for T2 (the paper's d′).
    anchors : tuple of str
    """

    user: np.ndarray
    target: np.ndarray
    target_index: np.ndarray
    time_s: np.ndarray
    rss: np.ndarray
    label: np.ndarray
    movement: np.ndarray
    position: np.ndarray
    pitch_true_rad: np.ndarray
    acc: np.ndarray
    acc_time_s: np.ndarray
    kinect: np.ndarray
    kinect_time_s: np.ndarray
    segment_length_m: np.ndarray
    device_offset_m: np.ndarray
    anchors: tuple[str, ...]

    def __len__(self) -> int:
        return self.time_s.size

    def select(self, *, user=None, target=None, movement=None, label=None) -> DynamicData:
        """Rows matching every given value (a value or a collection; ``movement`` numbers)."""
        return select_rows(self, user=user, target=target, movement=movement, label=label)


def movement_number(labels) -> np.ndarray:
    """Movement number (int) of each label: ``k`` for ``"M<k>_…"``, 0 for anything else."""
    out = []
    for label in np.asarray(labels, dtype=object).ravel():
        match = _MOVEMENT_RE.match(str(label))
        out.append(int(match.group(1)) if match else 0)
    return np.asarray(out, dtype=int).reshape(np.shape(labels))


def _latest(sample_times: np.ndarray, query: np.ndarray, what: str, where: str) -> np.ndarray:
    index = np.searchsorted(sample_times, query, side="right") - 1
    if np.any(index < 0):
        first = float(query[int(np.argmax(index < 0))])
        raise ValueError(f"{where}: no {what} sample at or before the RSS vector at {first:.6f} s")
    return index


def align_dynamic(rss: pd.DataFrame, acc: pd.DataFrame, kinect: pd.DataFrame, chains: dict[str, ArmChain], *,
                  session: str = DYNAMIC_SESSION) -> DynamicData:
    """Pair every RSS vector of ``session`` with the latest accelerometer sample and Kinect
    estimate at or before it (module docstring).

    Parameters
    ----------
    rss : pandas.DataFrame
        Long RSS table (:mod:`wsnlib.io.rss`); rows of other sessions are ignored.
    acc, kinect : pandas.DataFrame
        Long sample tables (:mod:`wsnlib.io.accel`) covering the same users and session.
    chains : dict
        ``{user: ArmChain}`` (``User.geometry``) for every user of the session.
    session : str

    Returns
    -------
    DynamicData

    Raises
    ------
    ValueError
        A user without chain, accelerometer or Kinect rows, or an RSS vector earlier than every
        accelerometer sample or Kinect frame of its target.
    """
    sub = rss[rss["session"] == session]
    if len(sub) == 0:
        raise ValueError(f"the RSS table has no rows of session {session!r}")
    vectors = rss_format.rss_vectors(sub, window_packets=1, fill="last")
    n = len(vectors)
    target_index = np.array([TARGET_NAMES.index(t) for t in vectors.target], dtype=int)
    acc_values, kin_values = np.empty((n, 3)), np.empty((n, 3))
    acc_time, kin_time, lengths, offsets = (np.empty(n) for _ in range(4))
    tables = (
        ("accelerometer", acc, accel.VALUE_COLUMNS["acc"], acc_values, acc_time),
        ("Kinect", kinect, accel.VALUE_COLUMNS["kinect"], kin_values, kin_time),
    )
    for user in pd.unique(vectors.user):
        if user not in chains:
            raise ValueError(f"chains has no ArmChain for user {user!r}")
        chain = chains[user]
        for t_idx, target in enumerate(TARGET_NAMES):
            rows = np.flatnonzero((vectors.user == user) & (target_index == t_idx))
            if rows.size == 0:
                continue
            query = vectors.time_s[rows]
            lengths[rows] = chain.segment_lengths_m[t_idx]
            offsets[rows] = chain.device_offsets_m[t_idx]
            for what, table, value_columns, values, times in tables:
                mask = ((table["user"] == user).to_numpy() & (table["session"] == session).to_numpy()
                        & (table["target"] == target).to_numpy())
                if not np.any(mask):
                    raise ValueError(f"no {what} rows for user {user!r}, session {session!r}, target {target}")
                part = table.loc[mask]
                sample_time = part["time_s"].to_numpy(dtype=float)
                order = np.argsort(sample_time, kind="stable")
                sample_time = sample_time[order]
                index = _latest(sample_time, query, what, f"user {user!r}, target {target}")
                values[rows] = part[list(value_columns)].to_numpy(dtype=float)[order][index]
                times[rows] = sample_time[index]
    position = vectors.position
    norm = np.linalg.norm(position, axis=-1)
    pitch = np.arcsin(np.clip(position[:, 2] / np.where(norm > 0, norm, 1.0), -1.0, 1.0))
    return DynamicData(user=vectors.user, target=vectors.target, target_index=target_index, time_s=vectors.time_s,
                       rss=vectors.rss, label=vectors.label, movement=movement_number(vectors.label), position=position,
                       pitch_true_rad=pitch, acc=acc_values, acc_time_s=acc_time, kinect=kin_values,
                       kinect_time_s=kin_time, segment_length_m=lengths, device_offset_m=offsets,
                       anchors=vectors.anchors)


# --------------------------------------------------------------------------------------------
# The dynamic campaign: RSS, accelerometers and Kinect of every user
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class DynamicCampaign:
    """Simulated training + online dynamic sessions with accelerometers and Kinect.

    Attributes
    ----------
    training_rss : pandas.DataFrame
        Long RSS table (:mod:`wsnlib.io.rss`) of every user's training session (day 0).
    dynamic_rss : pandas.DataFrame
        Long RSS table of every user's online dynamic session (session ``"online_dynamic"``,
        the online day), labels ``P1`` … ``P5`` (short holds), ``M1_…`` … ``M8_…`` and
        ``transition``.
    acc : pandas.DataFrame
        Long accelerometer table (:mod:`wsnlib.io.accel`, kind "acc") of the dynamic
        sessions: 30 Hz, both targets, m/s².  ``attrs["rate_hz"]`` = 30.
    kinect : pandas.DataFrame
        Long Kinect table (kind "kinect"): target positions from the simulated Kinect, 30 fps.
    data : DynamicData
        The RSS vectors of the dynamic sessions with everything aligned (:func:`align_dynamic`).
    users, online_users : tuple of User
        The users on the training day and on the online day (moved anchors, re-strapped
        targets: the online day's geometry is the one of the dynamic session).
    motions : tuple of ArmMotion
        Each user's dynamic-session motion (the one motion behind RSS, accelerometer and
        Kinect).
    acc_streams : tuple of SunspotAcc
        Each user's accelerometer streams, with the 100 Hz raw samples.
    kinect_streams : tuple of KinectStream
        Each user's Kinect frames, with true and reported joints.
    acc_spec : SunspotAccSpec
    kinect_model : KinectModel
    """

    training_rss: pd.DataFrame
    dynamic_rss: pd.DataFrame
    acc: pd.DataFrame
    kinect: pd.DataFrame
    data: DynamicData
    users: tuple[User, ...]
    online_users: tuple[User, ...]
    motions: tuple[ArmMotion, ...]
    acc_streams: tuple[SunspotAcc, ...]
    kinect_streams: tuple[KinectStream, ...]
    acc_spec: SunspotAccSpec
    kinect_model: KinectModel

    @property
    def chains(self) -> dict[str, ArmChain]:
        """``{user: ArmChain}`` of the online day (each user's :attr:`~wsnlib.sim.body.User.geometry`)."""
        return {u.name: u.geometry for u in self.online_users}


def simulate_dynamic_campaign(n_users: int = 5, *, rng: np.random.Generator, hold_s: float = 30.0, durations_s=None,
                              acc_spec: SunspotAccSpec | None = None, kinect_model: KinectModel | None = None,
                              camera_distance_m: float = PAPER_CAMERA_DISTANCE_M, channel: RadioChannel | None = None,
                              mounting=None) -> DynamicCampaign:
    """Training RSS and the online dynamic session with RSS, accelerometers and Kinect, per user.

    For each user, in this order from ``rng``: the training session
    (:func:`wsnlib.sim.radio.static_session`, postures held ``hold_s``), the online day
    (:meth:`User.moved`), the dynamic motion (:func:`wsnlib.sim.radio.online_dynamic_motion`:
    the four movements twice, 2–4 s each at constant speed, short holds and transitions),
    then — all from that one motion — its RSS (:func:`wsnlib.sim.radio.simulate_rss`, session
    ``"online_dynamic"``), its accelerometer streams (:func:`wsnlib.sim.sunspot.simulate_sunspot_acc`)
    and its Kinect frames (:func:`simulate_kinect_stream`).  The same seed gives the same
    campaign.

    Parameters
    ----------
    n_users, rng, hold_s
        As in :func:`simulate_campaign`.
    durations_s : array_like (8,), optional
        Durations of the 8 movements, the same for every user; default drawn per user
        uniformly in [2, 4] s.
    acc_spec : SunspotAccSpec, optional
        Accelerometer model; default :class:`SunspotAccSpec()`.
    kinect_model : KinectModel, optional
        Kinect error model; default :class:`KinectModel()`.
    camera_distance_m : float
        Kinect distance in front of the user (paper: about 3 m).
    channel : RadioChannel, optional
        Radio model; default :class:`RadioChannel()`.
    mounting : array_like (4,) or (2, 4), optional
        Accelerometer mounting (device → segment); default identity, so call
        ``pitch_from_acc`` with its default ``segment_axis``.

    Returns
    -------
    DynamicCampaign
    """
    n_users = check_count(n_users, "n_users")
    acc_spec = SunspotAccSpec() if acc_spec is None else acc_spec
    kinect_model = KinectModel() if kinect_model is None else kinect_model
    users = make_users(n_users, rng=rng)
    training, dynamic, online_users, motions, acc_streams, kinect_streams = [], [], [], [], [], []
    for user in users:
        training.append(static_session(user, rng=rng, hold_s=hold_s, session="training", channel=channel))
        day2 = user.moved(rng)
        motion = online_dynamic_motion(rng=rng, durations_s=durations_s)
        dynamic.append(simulate_rss(motion, day2, rng=rng, channel=channel, session=DYNAMIC_SESSION))
        acc_streams.append(simulate_sunspot_acc(motion, day2, rng=rng, spec=acc_spec, mounting=mounting))
        kinect_streams.append(simulate_kinect_stream(motion, day2, rng=rng, model=kinect_model,
                                                     camera_distance_m=camera_distance_m))
        online_users.append(day2)
        motions.append(motion)
    dynamic_rss = concat_rss(dynamic)
    acc_df = sample_table("acc", acc_streams, online_users, acc_spec.output_rate_hz)
    kinect_df = sample_table("kinect", kinect_streams, online_users, kinect_model.frame_rate_hz)
    chains = {u.name: u.geometry for u in online_users}
    return DynamicCampaign(training_rss=concat_rss(training), dynamic_rss=dynamic_rss, acc=acc_df, kinect=kinect_df,
                           data=align_dynamic(dynamic_rss, acc_df, kinect_df, chains), users=tuple(users),
                           online_users=tuple(online_users), motions=tuple(motions), acc_streams=tuple(acc_streams),
                           kinect_streams=tuple(kinect_streams), acc_spec=acc_spec, kinect_model=kinect_model)


#: File names written by :func:`write_dynamic_campaign` (CSV; each with its JSON sidecar).
DYNAMIC_FILES = {"training_rss": "training_rss.csv", "dynamic_rss": "dynamic_rss.csv", "acc": "acc.csv",
                 "kinect": "kinect.csv"}


def _dynamic_campaign_from_seed(n_users: int, seed: int, hold_s: float) -> DynamicCampaign:
    return simulate_dynamic_campaign(n_users, rng=np.random.default_rng(seed), hold_s=hold_s)


def dynamic_campaign(n_users: int = 5, *, seed: int, hold_s: float = 30.0) -> DynamicCampaign:
    """:func:`simulate_dynamic_campaign` from a fresh ``numpy.random.default_rng(seed)``, memoised.

    Notebooks 07–09 and their solutions share one campaign; the first to run simulates it,
    the others read it from ``build/cache/`` (:func:`wsnlib.cache.cached`, keyed by these
    arguments and wsnlib's source).  The result is the same either way.
    """
    from wsnlib.cache import cached

    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise ValueError(f"seed must be an integer, got {seed!r}")
    arguments = {"n_users": int(n_users), "seed": int(seed), "hold_s": float(hold_s)}
    return cached("dynamic_campaign", arguments, _dynamic_campaign_from_seed)


def write_dynamic_campaign(campaign: DynamicCampaign, folder, metadata: dict | None = None) -> dict[str, Path]:
    """Write the four tables of ``campaign`` into ``folder`` (:data:`DYNAMIC_FILES`).

    RSS with :func:`wsnlib.io.rss.write_rss`, accelerometer and Kinect with
    :func:`wsnlib.io.accel.write_samples`.  Every sidecar's metadata holds ``metadata``
    (e.g. the seed) and ``arm_chains`` (``{user: {segment_lengths_m, device_offsets_m}}`` of
    the online day, what :func:`read_dynamic_campaign` needs to rebuild :class:`DynamicData`);
    the accelerometer's also the sensor spec, the Kinect's the error model and camera distance.
    Byte-identical on rewrite.
    """
    check_type(campaign, DynamicCampaign, "campaign")
    folder = Path(folder)
    base = {} if metadata is None else dict(metadata)
    base["arm_chains"] = {user: {"segment_lengths_m": list(c.segment_lengths_m),
                                 "device_offsets_m": list(c.device_offsets_m)} for user, c in campaign.chains.items()}
    return {
        "training_rss": rss_format.write_rss(campaign.training_rss, folder / DYNAMIC_FILES["training_rss"], base),
        "dynamic_rss": rss_format.write_rss(campaign.dynamic_rss, folder / DYNAMIC_FILES["dynamic_rss"], base),
        "acc": accel.write_acc(campaign.acc, folder / DYNAMIC_FILES["acc"],
                               {**base, "acc_spec": dataclasses.asdict(campaign.acc_spec)}),
        "kinect": accel.write_kinect(campaign.kinect, folder / DYNAMIC_FILES["kinect"],
                                     {**base, "kinect_model": dataclasses.asdict(campaign.kinect_model)}),
    }


def read_dynamic_campaign(folder) -> tuple[dict[str, pd.DataFrame], dict[str, dict], DynamicData]:
    """Read what :func:`write_dynamic_campaign` wrote (or real logs converted to the same files).

    Returns
    -------
    tables : dict
        ``{"training_rss", "dynamic_rss", "acc", "kinect"}`` → DataFrame.
    sidecars : dict
        The same keys → sidecar dict.
    data : DynamicData
        :func:`align_dynamic` of the tables, with the chains of the dynamic RSS sidecar's
        ``metadata["arm_chains"]``.
    """
    folder = Path(folder)
    tables, sidecars = {}, {}
    for key in ("training_rss", "dynamic_rss"):
        tables[key], sidecars[key] = rss_format.read_rss(folder / DYNAMIC_FILES[key])
    tables["acc"], sidecars["acc"] = accel.read_acc(folder / DYNAMIC_FILES["acc"])
    tables["kinect"], sidecars["kinect"] = accel.read_kinect(folder / DYNAMIC_FILES["kinect"])
    raw = sidecars["dynamic_rss"]["metadata"].get("arm_chains")
    if not isinstance(raw, dict):
        raise ValueError(f"{folder / DYNAMIC_FILES['dynamic_rss']}: sidecar metadata has no 'arm_chains' object")
    chains = {user: ArmChain(tuple(c["segment_lengths_m"]), tuple(c["device_offsets_m"])) for user, c in raw.items()}
    return tables, sidecars, align_dynamic(tables["dynamic_rss"], tables["acc"], tables["kinect"], chains)
