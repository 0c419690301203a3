"""Simulation of both papers' set-ups; this package gathers the public names of its modules.

Paper 001's two-node arm: joint-angle trajectories and their exact kinematics (:mod:`.arm`),
and the IMU sensors (:mod:`.imu`; disturbances in :mod:`.disturbance`, calibrated against BROAD
with :mod:`.triad_calibration`; Monte Carlo trials with packet loss in :mod:`.trials`)::

    rng = np.random.default_rng(seed)
    trajectory = arm_extension(fs=50.0)
    truth = arm_kinematics(trajectory)                  # ArmKinematics: quat (2, T, 4), gyr, pos, acc_lin …
    gyr, acc, mag = simulate_imu(truth, rng=rng, n_runs=100)   # each (100, 2, T, 3)
    recording = simulate_recording(trajectory, rng=rng)        # wsnlib.io.recording.Recording

See the module docstrings for the body-frame convention and the datasheet sources.

Both papers share one arm model, :mod:`wsnlib.arm_model` (:class:`~wsnlib.arm_model.ArmGeometry`,
:class:`~wsnlib.arm_model.ArmKinematics` in the layout ``(node, T, C)``): paper 001's
joint-angle trajectories (:mod:`.arm`) and paper 002's straight-arm motions (:mod:`.arm_motion`)
both produce it.

Paper 002's radio testbed: the users and their bodies (:mod:`.body`), the arm's postures and
movements (:mod:`.arm_motion`), the radio channel, link budget, RSS recordings and sessions
(:mod:`.radio`), the SunSPOT accelerometer (:mod:`.sunspot`), the
Kinect and the paper's hand-derived reference (:mod:`.optical`) and whole campaigns
(:mod:`.campaign`)::

    users = make_users(5, rng=rng)
    train = static_session(users[0], rng=rng, hold_s=30.0, session="training")  # long RSS table
    online = online_dynamic_session(users[0].moved(rng), rng=rng)   # another day
    kin = movement("lower_P2_P3_P1", 3.0).sample(users[0], fs=50.0)  # ArmKinematics

Which notebook each module serves (directly, or through :mod:`wsnlib.studies`; "sol": the
solutions notebook of the same number; notebook 05 uses only the arm, for the paper's movement,
notebooks 10 and 11 nothing, and ``benchmarks/bench_madgwick.py`` uses :mod:`.arm` and :mod:`.imu`):

==========================  =================================================================================
module                      notebooks
==========================  =================================================================================
:mod:`.arm`                 01–05, sol 01–04
:mod:`.imu`                 01–04, sol 01–04
:mod:`.disturbance`         01–04, sol 03 (calibrated in 03; 01, 02 and 04 simulate with its ``UNDISTURBED_BROAD``)
:mod:`.triad_calibration`   03 (TRIAD's error, simulated against BROAD: the calibration's fit)
:mod:`.trials`              02–04, sol 03, sol 04
:mod:`.body`                06–09, sol 06–09
:mod:`.arm_motion`          06–09, sol 06–09
:mod:`.radio`               06–09, sol 06–09 (08 also perturbs the channel: radio sensitivity)
:mod:`.sunspot`             07–09, sol 07–09
:mod:`.optical`             Kinect 07–09 and sol 07–09; the hand-derived reference 09 only
:mod:`.campaign`            06 and sol 06 (``simulate_campaign``); 07–09 and sol 07–09 (``dynamic_campaign``)
==========================  =================================================================================
"""

from wsnlib.sim.arm import (
    ArmTrajectory,
    arm_extension,
    arm_kinematics,
    minimum_jerk,
    movement_set,
    pitch_ramp,
    reach_and_flex,
)
from wsnlib.sim.arm_motion import ArmMotion, arc, concatenate, hold, movement, transition
from wsnlib.sim.body import BodyShape, User, make_users, user_from_height
from wsnlib.sim.imu import ImuSamples, ImuSpec, ideal_imu, simulate_imu, simulate_recording
from wsnlib.sim.radio import (
    RadioChannel,
    concat_rss,
    link_budget,
    online_dynamic_session,
    simulate_rss,
    static_session,
)

__all__ = [
    "ArmMotion", "ArmTrajectory", "BodyShape", "ImuSamples", "ImuSpec", "RadioChannel", "User", "arc",
    "arm_extension", "arm_kinematics", "concat_rss", "concatenate", "hold", "ideal_imu", "link_budget", "make_users",
    "minimum_jerk", "movement", "movement_set", "online_dynamic_session", "pitch_ramp",
    "reach_and_flex", "simulate_imu", "simulate_recording", "simulate_rss", "static_session",
    "transition", "user_from_height",
]
