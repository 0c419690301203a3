"""Monte Carlo trials for the loss studies: movements × loss profiles × noise/loss seeds.

A *trial* is one simulated recording of the two arm nodes (independent sensor noise) with one
loss mask per node.  :func:`arm_loss_trials` stacks every (movement, loss profile, repetition)
along one leading axis, so a whole study is one batched filter call.

Loss profiles (:class:`wsnlib.loss.LossProfile`) per node, paper 001's way:

* ``LossProfile.burst(start_s, n_packets=4)`` — Section IV: the humerus loses ``n_packets``
  consecutive packets right after ``start_s`` seconds (80 samples = 1.6 s at 50 Hz); the
  forearm loses nothing;
* ``LossProfile.gilbert_elliott(loss_rate, mean_burst_packets=3)`` — bursty random loss on
  *both* nodes, independently (two radios), packets of 6 samples;
* ``LossProfile.none()`` — everything received (the lossless reference).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnlib._validation import check_count
from wsnlib.loss import LossProfile
from wsnlib.sim.arm import ArmTrajectory, arm_kinematics
from wsnlib.sim.disturbance import Disturbance
from wsnlib.sim.imu import ImuSpec, simulate_imu


@dataclass(frozen=True)
class Trials:
    """Stacked Monte Carlo trials; axis 0 enumerates trials, axis 1 the nodes (humerus, forearm).

    Attributes
    ----------
    gyr, acc, mag : numpy.ndarray, shape (R, 2, T, 3)
        rad/s, m/s², µT, body frame.
    quat_true : numpy.ndarray, shape (R, 2, T, 4)
        Ground truth, ENU.
    received : numpy.ndarray of bool, shape (R, 2, T)
    labels : pandas.DataFrame
        One row per trial: ``movement``, ``profile``, ``repetition``.
    fs : float
        Hz.
    """

    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray
    quat_true: np.ndarray
    received: np.ndarray
    labels: pd.DataFrame
    fs: float

    def select(self, keep) -> Trials:
        """The trials where ``keep`` is True, in their order (labels renumbered from 0).

        Parameters
        ----------
        keep : array_like of bool, shape (R,)

        Returns
        -------
        Trials

        Examples
        --------
        Long outages on short records can leave a node with no received sample at all, which
        Madgwick's filter cannot start from (without ``q0``) and single frame cannot hold;
        drop those trials with ``trials.select(trials.received.any(axis=-1).all(axis=-1))``.
        """
        keep = np.asarray(keep)
        n_trials = self.received.shape[0]
        if keep.dtype != np.bool_ or keep.shape != (n_trials,):
            raise ValueError(f"keep must be a boolean array of shape ({n_trials},), got dtype {keep.dtype}, "
                             f"shape {keep.shape}")
        return Trials(gyr=self.gyr[keep], acc=self.acc[keep], mag=self.mag[keep], quat_true=self.quat_true[keep],
                      received=self.received[keep], labels=self.labels[keep].reset_index(drop=True), fs=self.fs)


def arm_loss_trials(movements: dict[str, ArmTrajectory], profiles: list[LossProfile], n_repetitions: int, *,
                    rng: np.random.Generator, spec: ImuSpec | None = None,
                    disturbance: Disturbance | None = None) -> Trials:
    """Simulate every movement × loss profile × repetition, stacked along axis 0.

    Every trial has its own sensor noise and its own loss draw; trials are ordered by
    movement, then profile, then repetition.

    Parameters
    ----------
    movements : dict[str, ArmTrajectory]
        All with the same number of samples and sampling rate (e.g.
        :func:`wsnlib.sim.arm.movement_set`).
    profiles : list of wsnlib.loss.LossProfile
    n_repetitions : int
        Trials per (movement, profile), ≥ 1.
    rng : numpy.random.Generator
    spec : ImuSpec, optional
        Sensor model (datasheet defaults).
    disturbance : Disturbance, optional
        Magnetic disturbance and body translation added to every trial (each trial draws its
        own; :data:`wsnlib.sim.disturbance.UNDISTURBED_BROAD` is calibrated to BROAD); None
        (default) gives exactly the clean trials.

    Returns
    -------
    Trials
    """
    if not movements or not profiles:
        raise ValueError("movements and profiles must not be empty")
    check_count(n_repetitions, "n_repetitions")
    lengths = {(m.n_samples, m.fs) for m in movements.values()}
    if len(lengths) != 1:
        raise ValueError(f"movements must share length and fs, got (T, fs) = {sorted(lengths)}")
    (n_samples, fs), = lengths
    per_movement = len(profiles) * n_repetitions
    parts = {"gyr": [], "acc": [], "mag": [], "quat_true": [], "received": []}
    labels = []
    for name, trajectory in movements.items():
        truth = arm_kinematics(trajectory)
        gyr, acc, mag = simulate_imu(truth, spec, rng=rng, n_runs=per_movement, disturbance=disturbance)
        parts["gyr"].append(gyr)
        parts["acc"].append(acc)
        parts["mag"].append(mag)
        parts["quat_true"].append(np.broadcast_to(truth.quat, (per_movement,) + truth.quat.shape))
        for profile in profiles:
            received = profile.mask(n_samples, fs, rng, shape=(n_repetitions, 2))
            if profile.model == "burst":
                received[:, 1] = True  # the burst is the humerus's only
            parts["received"].append(received)
            labels += [{"movement": name, "profile": profile.name, "repetition": r} for r in range(n_repetitions)]
    stacked = {key: np.concatenate(value) for key, value in parts.items()}
    return Trials(**stacked, labels=pd.DataFrame(labels), fs=float(fs))
