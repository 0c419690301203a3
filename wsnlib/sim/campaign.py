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

The pieces live in their own modules, re-exported here (old path):
:mod:`wsnlib.sim.dynamic_data` (the clock, the long accelerometer and Kinect tables, the
alignment :func:`align_dynamic` and :class:`DynamicData`) and :mod:`wsnlib.sim.kinect_stream`
(the Kinect's view of one user, :func:`simulate_kinect_stream`).  This module simulates the
campaigns, memoises the notebooks' one (:func:`dynamic_campaign`) and writes / reads its files
(:func:`write_dynamic_campaign`, :func:`read_dynamic_campaign`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from wsnlib.arm_model import ArmGeometry
from wsnlib.io import accel as accel_format
from wsnlib.io import rss as rss_format
from wsnlib.posture import ArmChain
from wsnlib.sim.arm_motion import ArmMotion

# Re-exported here (their old home): the dynamic session's data model and the Kinect stream.
from wsnlib.sim.dynamic_data import (  # noqa: F401
    DYNAMIC_SESSION,
    DynamicData,
    acc_table,
    align_dynamic,
    concat_sample_tables,
    kinect_table,
    movement_number,
)
from wsnlib.sim.kinect_model import PAPER_CAMERA_DISTANCE_M, KinectModel
from wsnlib.sim.kinect_stream import (  # noqa: F401
    CAMERA_HEIGHT_175_M,
    KinectStream,
    kinect_camera,
    simulate_kinect_stream,
)
from wsnlib.sim.radio import (
    RadioChannel,
    concat_rss,
    online_dynamic_motion,
    online_dynamic_session,
    online_static_session,
    simulate_rss,
    training_session,
)
from wsnlib.sim.sunspot import SunspotAcc, SunspotAccSpec, simulate_sunspot_acc
from wsnlib.sim.users import User, make_users


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
        Seconds each posture is held in the online static session.
    dynamic : bool
        Also simulate the online dynamic session (8 movements).

    Returns
    -------
    Campaign
    """
    if not isinstance(n_users, int | np.integer) or n_users < 1:
        raise ValueError(f"n_users must be a positive integer, got {n_users!r}")
    users = make_users(n_users, rng=rng)
    frames, online_users = [], []
    for user in users:
        frames.append(training_session(user, rng=rng, hold_s=hold_s))
        day2 = user.moved(rng)
        online_users.append(day2)
        frames.append(online_static_session(day2, rng=rng, hold_s=static_hold_s))
        if dynamic:
            frames.append(online_dynamic_session(day2, rng=rng))
    return Campaign(rss=concat_rss(frames), users=tuple(users), online_users=tuple(online_users))


# --------------------------------------------------------------------------------------------
# The online dynamic session with accelerometers and a Kinect, on one clock (the data model
# and the alignment: wsnlib.sim.dynamic_data)
# --------------------------------------------------------------------------------------------


def arm_chain(user: User) -> ArmGeometry:
    """``user.geometry``: kept for old scripts; the user's arm is :attr:`wsnlib.sim.users.User.geometry`
    (an :class:`wsnlib.arm_model.ArmGeometry`, which is :class:`wsnlib.posture.ArmChain`)."""
    return user.geometry


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
        """``{user: ArmChain}`` of the online day (each user's :attr:`~wsnlib.sim.users.User.geometry`)."""
        return {u.name: u.geometry for u in self.online_users}


def simulate_dynamic_campaign(
    n_users: int = 5,
    *,
    rng: np.random.Generator,
    hold_s: float = 30.0,
    durations_s=None,
    acc_spec: SunspotAccSpec | None = None,
    kinect_model: KinectModel | None = None,
    camera_distance_m: float = PAPER_CAMERA_DISTANCE_M,
    channel: RadioChannel | None = None,
    mounting=None,
) -> DynamicCampaign:
    """Training RSS and the online dynamic session with RSS, accelerometers and Kinect, per user.

    For each user, in this order from ``rng``: the training session
    (:func:`wsnlib.sim.radio.training_session`, postures held ``hold_s``), the online day
    (:meth:`User.moved`), the dynamic motion (:func:`wsnlib.sim.radio.online_dynamic_motion`:
    the four movements twice, 2–4 s each at constant speed, short holds and transitions),
    then — all from that one motion — its RSS (:func:`wsnlib.sim.radio.simulate_rss`, session
    ``"online_dynamic"``), its accelerometer streams (:func:`wsnlib.sim.sunspot.simulate_sunspot_acc`)
    and its Kinect frames (:func:`simulate_kinect_stream`).  The same seed gives the same
    campaign.

    Parameters
    ----------
    n_users : int
        Number of users (paper 002: five).
    rng : numpy.random.Generator
    hold_s : float
        Seconds each posture is held in training (paper: about 30 s).
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
    if isinstance(n_users, bool) or not isinstance(n_users, int | np.integer) or n_users < 1:
        raise ValueError(f"n_users must be a positive integer, got {n_users!r}")
    acc_spec = SunspotAccSpec() if acc_spec is None else acc_spec
    kinect_model = KinectModel() if kinect_model is None else kinect_model
    users = make_users(int(n_users), rng=rng)
    training, dynamic, acc_frames, kinect_frames = [], [], [], []
    online_users, motions, acc_streams, kinect_streams = [], [], [], []
    for user in users:
        training.append(training_session(user, rng=rng, hold_s=hold_s, channel=channel))
        day2 = user.moved(rng)
        motion = online_dynamic_motion(rng=rng, durations_s=durations_s)
        dynamic.append(simulate_rss(motion, day2, rng=rng, channel=channel, session=DYNAMIC_SESSION))
        acc = simulate_sunspot_acc(motion, day2, rng=rng, spec=acc_spec, mounting=mounting)
        kinect = simulate_kinect_stream(motion, day2, rng=rng, model=kinect_model, camera_distance_m=camera_distance_m)
        acc_frames.append(acc_table(acc, day2.name))
        kinect_frames.append(kinect_table(kinect, day2.name))
        online_users.append(day2)
        motions.append(motion)
        acc_streams.append(acc)
        kinect_streams.append(kinect)
    dynamic_rss = concat_rss(dynamic)
    acc_df = concat_sample_tables(acc_frames, acc_spec.output_rate_hz)
    kinect_df = concat_sample_tables(kinect_frames, kinect_model.frame_rate_hz)
    chains = {u.name: u.geometry for u in online_users}
    return DynamicCampaign(
        training_rss=concat_rss(training),
        dynamic_rss=dynamic_rss,
        acc=acc_df,
        kinect=kinect_df,
        data=align_dynamic(dynamic_rss, acc_df, kinect_df, chains),
        users=tuple(users),
        online_users=tuple(online_users),
        motions=tuple(motions),
        acc_streams=tuple(acc_streams),
        kinect_streams=tuple(kinect_streams),
        acc_spec=acc_spec,
        kinect_model=kinect_model,
    )


#: File names written by :func:`write_dynamic_campaign` (CSV; each with its JSON sidecar).
DYNAMIC_FILES = {
    "training_rss": "training_rss.csv",
    "dynamic_rss": "dynamic_rss.csv",
    "acc": "acc.csv",
    "kinect": "kinect.csv",
}


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


def _chains_json(chains: dict[str, ArmChain]) -> dict:
    return {
        user: {"segment_lengths_m": list(c.segment_lengths_m), "device_offsets_m": list(c.device_offsets_m)}
        for user, c in chains.items()
    }


def write_dynamic_campaign(campaign: DynamicCampaign, folder, metadata: dict | None = None) -> dict[str, Path]:
    """Write the four tables of ``campaign`` into ``folder`` (:data:`DYNAMIC_FILES`).

    RSS with :func:`wsnlib.io.rss.write_rss`, accelerometer and Kinect with
    :func:`wsnlib.io.accel.write_samples`.  Every sidecar's metadata holds ``metadata``
    (e.g. the seed) and ``arm_chains`` (``{user: {segment_lengths_m, device_offsets_m}}`` of
    the online day, what :func:`read_dynamic_campaign` needs to rebuild :class:`DynamicData`);
    the accelerometer's also the sensor spec, the Kinect's the error model and camera distance.
    Byte-identical on rewrite.
    """
    if not isinstance(campaign, DynamicCampaign):
        raise ValueError(f"campaign must be a DynamicCampaign, got {type(campaign).__name__}")
    folder = Path(folder)
    base = {} if metadata is None else dict(metadata)
    base["arm_chains"] = _chains_json(campaign.chains)
    paths = {
        "training_rss": rss_format.write_rss(campaign.training_rss, folder / DYNAMIC_FILES["training_rss"], base),
        "dynamic_rss": rss_format.write_rss(campaign.dynamic_rss, folder / DYNAMIC_FILES["dynamic_rss"], base),
        "acc": accel_format.write_acc(
            campaign.acc, folder / DYNAMIC_FILES["acc"], {**base, "acc_spec": dataclasses.asdict(campaign.acc_spec)}
        ),
        "kinect": accel_format.write_kinect(
            campaign.kinect,
            folder / DYNAMIC_FILES["kinect"],
            {**base, "kinect_model": dataclasses.asdict(campaign.kinect_model)},
        ),
    }
    return paths


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
    tables["acc"], sidecars["acc"] = accel_format.read_acc(folder / DYNAMIC_FILES["acc"])
    tables["kinect"], sidecars["kinect"] = accel_format.read_kinect(folder / DYNAMIC_FILES["kinect"])
    raw = sidecars["dynamic_rss"]["metadata"].get("arm_chains")
    if not isinstance(raw, dict):
        raise ValueError(f"{folder / DYNAMIC_FILES['dynamic_rss']}: sidecar metadata has no 'arm_chains' object")
    chains = {user: ArmChain(tuple(c["segment_lengths_m"]), tuple(c["device_offsets_m"])) for user, c in raw.items()}
    return tables, sidecars, align_dynamic(tables["dynamic_rss"], tables["acc"], tables["kinect"], chains)
