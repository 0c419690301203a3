"""RSS of paper 002's testbed: 2 targets on the arm × 7 anchors, IEEE 802.15.4 at 2.4 GHz.

The radio simulator, in files of one concern (this module re-exports them; its names keep
working):

* :mod:`wsnlib.sim.radio_channel` — the model (equations, sources and status of every number)
  and its parameters: :class:`PathLossModel`, :class:`RadioChannel`;
* :mod:`wsnlib.sim.radio_links` — the deterministic link budget from the arm's kinematics
  (:class:`wsnlib.arm_model.ArmKinematics`) and the body: :func:`link_budget`,
  :func:`antenna_positions`, :func:`dipole_gain_db`;
* :mod:`wsnlib.sim.radio_rss` — packets and temporal randomness: :func:`simulate_rss`,
  :func:`packet_times`, :func:`concat_rss`, :func:`gauss_markov`, :func:`rician_fading_db`;
* :mod:`wsnlib.sim.radio_sessions` — paper 002's sessions: :func:`static_session` (with the
  wrappers :func:`training_session` and :func:`online_static_session`),
  :func:`online_dynamic_session`, :func:`online_dynamic_motion`.
"""

from wsnlib.sim.radio_channel import (
    FREQUENCY_HZ,
    OFFBODY,
    ONBODY_LOS,
    ONBODY_NLOS,
    SPEED_OF_LIGHT,
    WORN_ANTENNA_LOSS_DB,
    PathLossModel,
    RadioChannel,
    free_space_loss_db,
)
from wsnlib.sim.radio_links import LIMB_SOLIDS, LinkBudget, antenna_positions, dipole_gain_db, link_budget
from wsnlib.sim.radio_rss import RSS_COLUMNS, concat_rss, gauss_markov, packet_times, rician_fading_db, simulate_rss
from wsnlib.sim.radio_sessions import (
    movement_label,
    online_dynamic_motion,
    online_dynamic_session,
    online_static_session,
    posture_mean_rss,
    static_session,
    training_session,
)

__all__ = [
    "FREQUENCY_HZ",
    "LIMB_SOLIDS",
    "OFFBODY",
    "ONBODY_LOS",
    "ONBODY_NLOS",
    "RSS_COLUMNS",
    "SPEED_OF_LIGHT",
    "WORN_ANTENNA_LOSS_DB",
    "LinkBudget",
    "PathLossModel",
    "RadioChannel",
    "antenna_positions",
    "concat_rss",
    "dipole_gain_db",
    "free_space_loss_db",
    "gauss_markov",
    "link_budget",
    "movement_label",
    "online_dynamic_motion",
    "online_dynamic_session",
    "online_static_session",
    "packet_times",
    "posture_mean_rss",
    "rician_fading_db",
    "simulate_rss",
    "static_session",
    "training_session",
]
