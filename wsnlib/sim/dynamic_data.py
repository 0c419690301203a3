"""The online dynamic session of paper 002 on one clock: long accelerometer and Kinect tables
(:func:`acc_table`, :func:`kinect_table`) and every RSS vector paired with the samples an
online system had when it arrived (:func:`align_dynamic` → :class:`DynamicData`).

Simulated by :func:`wsnlib.sim.campaign.simulate_dynamic_campaign`; real logs converted to the
same files (:func:`wsnlib.sim.campaign.read_dynamic_campaign`) give the same :class:`DynamicData`.

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
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from wsnlib.io import accel as accel_format
from wsnlib.io import rss as rss_format
from wsnlib.posture import ArmChain
from wsnlib.testbed import TARGET_NAMES

if TYPE_CHECKING:  # annotations only
    from wsnlib.sim.kinect_stream import KinectStream
    from wsnlib.sim.sunspot import SunspotAcc

#: Session name of the online dynamic session (as :func:`wsnlib.sim.radio.online_dynamic_session`).
DYNAMIC_SESSION = "online_dynamic"

_MOVEMENT_RE = re.compile(r"^M(\d+)_")


def acc_table(acc: SunspotAcc, user: str, session: str = DYNAMIC_SESSION) -> pd.DataFrame:
    """Long accelerometer table (:mod:`wsnlib.io.accel`, kind "acc") of one session.

    Values rounded to 6 decimals (the CSV precision), rows ordered by time, then target.
    """
    return _long_table(acc.time_s, acc.acc, acc.label, user, session, accel_format.VALUE_COLUMNS["acc"])


def kinect_table(stream: KinectStream, user: str, session: str = DYNAMIC_SESSION) -> pd.DataFrame:
    """Long Kinect table (:mod:`wsnlib.io.accel`, kind "kinect") of one session (as :func:`acc_table`)."""
    return _long_table(stream.time_s, stream.targets, stream.label, user, session, accel_format.VALUE_COLUMNS["kinect"])


def _long_table(time, values, label, user, session, value_columns) -> pd.DataFrame:
    n, n_targets = values.shape[:2]
    flat = values.reshape(n * n_targets, 3)
    table = {
        "time_s": np.repeat(time, n_targets),
        "user": user,
        "session": session,
        "target": np.tile(np.asarray(TARGET_NAMES[:n_targets], dtype=object), n),
        "label": np.repeat(np.asarray(label, dtype=object), n_targets),
    }
    for j, column in enumerate(value_columns):
        table[column] = np.round(flat[:, j], 6) + 0.0  # the CSV precision, so memory and file agree
    df = pd.DataFrame(table)
    df = df.astype({"user": object, "session": object, "target": object, "label": object})
    return df


def concat_sample_tables(frames, rate_hz: float) -> pd.DataFrame:
    """Concatenate long sample tables (:func:`acc_table`, :func:`kinect_table`); ``attrs["rate_hz"]`` = ``rate_hz``."""
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
        keep = np.ones(len(self), dtype=bool)
        for name, wanted in (("user", user), ("target", target), ("movement", movement), ("label", label)):
            if wanted is None:
                continue
            wanted = [wanted] if isinstance(wanted, str | int | np.integer) else list(wanted)
            keep &= np.isin(getattr(self, name), wanted)
        values = {
            f.name: getattr(self, f.name)[keep] for f in dataclasses.fields(self) if f.name != "anchors"
        }
        return DynamicData(**values, anchors=self.anchors)

    def arm_chain(self, user: str) -> ArmChain:
        """The user's :class:`wsnlib.posture.ArmChain` (segment lengths and device offsets)."""
        rows = self.user == user
        if not np.any(rows):
            raise ValueError(f"no rows for user {user!r}")
        lengths, offsets = [], []
        for i in range(len(TARGET_NAMES)):
            sel = rows & (self.target_index == i)
            if not np.any(sel):
                raise ValueError(f"user {user!r} has no rows of target {TARGET_NAMES[i]}")
            first = int(np.argmax(sel))
            lengths.append(float(self.segment_length_m[first]))
            offsets.append(float(self.device_offset_m[first]))
        return ArmChain(segment_lengths_m=tuple(lengths), device_offsets_m=tuple(offsets))


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


def align_dynamic(
    rss: pd.DataFrame,
    acc: pd.DataFrame,
    kinect: pd.DataFrame,
    chains: dict[str, ArmChain],
    *,
    session: str = DYNAMIC_SESSION,
) -> DynamicData:
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
    acc_values = np.empty((n, 3))
    acc_time = np.empty(n)
    kin_values = np.empty((n, 3))
    kin_time = np.empty(n)
    lengths = np.empty(n)
    offsets = np.empty(n)
    tables = (
        ("accelerometer", acc, accel_format.VALUE_COLUMNS["acc"], acc_values, acc_time),
        ("Kinect", kinect, accel_format.VALUE_COLUMNS["kinect"], kin_values, kin_time),
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
                mask = (
                    (table["user"] == user).to_numpy()
                    & (table["session"] == session).to_numpy()
                    & (table["target"] == target).to_numpy()
                )
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
    return DynamicData(
        user=vectors.user,
        target=vectors.target,
        target_index=target_index,
        time_s=vectors.time_s,
        rss=vectors.rss,
        label=vectors.label,
        movement=movement_number(vectors.label),
        position=position,
        pitch_true_rad=pitch,
        acc=acc_values,
        acc_time_s=acc_time,
        kinect=kin_values,
        kinect_time_s=kin_time,
        segment_length_m=lengths,
        device_offset_m=offsets,
        anchors=vectors.anchors,
    )
