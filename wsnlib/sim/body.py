"""Body, users, arm postures and movements of paper 002's testbed (Giuberti et al., Sec. 4.1).

The user stands still; two targets are strapped to the straight right arm (T1 mid upper arm,
T2 mid forearm); seven anchors are worn (A1, A4, A6, A7: t-shirt pockets and a hat) or fixed
in the room (A2, A3, A5).  This module holds the geometry; :mod:`wsnlib.sim.radio` turns it
into received signal strengths.

Shoulder frame
--------------
Origin at the centre of the right shoulder joint; **x** to the user's right (lateral),
**y** forward, **z** up (paper 002, footnote 4: z vertical, y forward, x normal to the
sagittal plane; the signs follow Table 1: P4, the arm held out sideways, has x > 0, and P5,
across the body, has x < 0).  The frame is right-handed and is the package's ENU earth frame
for a user facing north, so quaternions, angular rates and accelerations here follow
``wsnlib/__init__.py`` unchanged.  Lengths are in metres.

Postures (paper 002, Table 1)
-----------------------------
The arm is straight in every posture, so both targets lie on one ray from the shoulder, at
``d1`` (T1) and ``d2`` (T2) along the arm direction ``u``:

====  =============================  =========================================
P1    arm down                       u = (0, 0, −1)
P2    arm up                         u = (0, 0, +1)
P3    forward, horizontal            u = (0, +1, 0)
P4    sideways (right), horizontal   u = (+1, 0, 0)
P5    across the body, horizontal    u = (−sin 56.7°, cos 56.7°, 0)
====  =============================  =========================================

Table 1's P5 entries, T1 (−11, 11, 0) cm and T2 (−34, 21, 0) cm, are not collinear with the
shoulder (45° and 58° across the body; T2 is 40 cm from the shoulder, not 42.5 cm), so no
straight arm passes through both.  We take the straight arm that fits both points in least
squares, ``u ∝ d1·T1 + d2·T2`` (56.7° across the body), which misses the table by 3.2 cm
(T1) and 2.7 cm (T2).  :data:`TABLE1_POSITIONS_CM` keeps the table verbatim.

Segment (node) frames follow :mod:`wsnlib.arm_model`: body x along the segment (distal), body
z "dorsal" (up when the arm points forward palm down), body y = z × x.  A posture's
orientation is ``R_z(ψ) ⊗ q_ref ⊗ R_y(−θ)`` with heading ψ and pitch θ of ``u`` (ψ = 0 for
the vertical postures), i.e. each posture is P3 turned rigidly about the vertical (P4, P5) or
the lateral axis (P1, P2).  Moving the arm along the paper's movements reproduces exactly
these orientations at the end points (tested).

Movements (paper 002, Sec. 4.1 and Fig. 5)
------------------------------------------
Four transitional movements, each at constant angular speed (the paper's users were asked to
move "at constant speed", 2–4 s per movement), each a rotation of the straight arm about one
fixed axis through the shoulder:

* ``lower_P2_P3_P1``: from P2 down through P3 to P1 (180° about −x);
* ``horizontal_P4_P3_P5``: from P4 through P3 to P5 (146.7° about +z);
* ``raise_P1_P3``: from P1 up to P3 (90° about −x);
* ``horizontal_P3_P4``: from P3 to P4 (90° about −z).

:func:`arc` builds any constant-speed great-circle arc between two directions (SLERP of the
directions), optionally through a via-point (two great-circle pieces at the same angular
speed; the angular velocity jumps at the via-point unless both pieces share the axis, as in
the paper's movements).  Angular acceleration is zero inside every piece; the steps of the
angular velocity at the start and end of a constant-speed movement are idealised away (a
real arm needs some 100 ms to get up to speed).

Users and anchors
-----------------
Segment lengths from body height H (D. A. Winter, *Biomechanics and Motor Control of Human
Movement*, 4th ed., Wiley 2009, Fig. 4.1, after Drillis & Contini 1966: upper arm 0.186 H,
forearm 0.146 H, shoulder height 0.818 H; see :mod:`wsnlib.sim.arm` for how far these were
checked).  Paper 002's own user had T1 at 15 cm and T2 at 42.5 cm: upper arm 30 cm and
forearm 25 cm (:func:`paper_user`), i.e. H ≈ 1.62 m by Winter's fractions.

The paper's anchor placement (its Fig. 4) is not in the text, so the sites below are our
choice, made to be plausible for "a home-made t-shirt with folders" and "a hat" and to give
the targets a mix of short line-of-sight and body-shadowed links:

====  ======  =============================================================================
A1    worn    left chest pocket, on the front of the torso at sternum height
A2    room    on a table 1.5 m in front and 1.0 m to the right, 0.75 m above the floor
A3    room    on a shelf 2.0 m to the right and 0.3 m behind, 1.80 m above the floor
A4    worn    upper back, between the shoulder blades
A5    room    on a stand 2.5 m in front and 1.2 m to the left, 1.20 m above the floor
A6    worn    right front of the waist (belt pocket)
A7    worn    on the hat, top front of the head
====  =============================================================================

Worn sites scale with H (given for H = 1.75 m, 1 cm outside the modelled body surface for
the pocket/cloth); room sites are fixed in the room (heights above the floor), the user
standing on a floor mark.  :func:`make_users` jitters worn anchors by σ = 2 cm per axis
(fit of the t-shirt on different users, assumed) and the floor mark by σ = 2 cm per
horizontal axis (assumed).  :meth:`User.moved` is a later day: the t-shirt re-donned (worn
anchors σ = 1.5 cm per axis), the user on the mark again (σ = 2 cm horizontally), the targets
re-strapped (σ = 1 cm along the arm) — all assumed.

Body for shadowing
------------------
Simple solids in the shoulder frame, for a 1.75 m adult and scaled by H / 1.75 m (all sizes
assumed, of the order of adult anthropometric averages; chest breadth ≈ 30 cm, chest depth
≈ 22 cm):

* torso: vertical elliptic cylinder, semi-axes 0.15 m (lateral) × 0.11 m (front–back),
  centred 0.19 m to the left of the shoulder joint (joint centres ≈ 38 cm apart), from
  0.60 m below the shoulder to shoulder level;
* legs (one block): vertical elliptic cylinder 0.15 × 0.10 m from the floor to the torso;
* neck: vertical cylinder, radius 0.06 m, from shoulder level up 0.10 m;
* head: sphere, radius 0.10 m, centre 0.205 m above the shoulder (0.935 H − 0.818 H);
* left arm: hanging straight down, cylinder of radius 0.045 m, 0.58 m long;
* right arm: upper arm cylinder radius 0.045 m, forearm 0.040 m, along the arm direction.

The targets sit on the lateral surface of their segment (body −y of the segment frame, 1 cm
outside the modelled skin): that is where the radio antenna is.  The positions written to
recordings and compared with estimates are the points on the arm axis (Table 1 convention).

Where the code is
-----------------
The code is in files of one concern, re-exported here (this module's names keep working):

* :mod:`wsnlib.sim.users` — :class:`BodyShape`, anchor sites, :class:`User` (with its arm as
  :attr:`User.geometry`), :func:`make_users`, :func:`paper_user`, :func:`user_from_height`;
* :mod:`wsnlib.sim.arm_motion` — :class:`ArmMotion` and its builders :func:`hold`,
  :func:`arc`, :func:`movement`, :func:`rotate_to`, :func:`transition`, :func:`concatenate`;
* :mod:`wsnlib.sim.body_solids` — :class:`Solid`, :func:`body_solids`, :func:`chord_length`;
* :mod:`wsnlib.arm_model` — the arm's geometry and kinematics shared by both papers
  (:class:`~wsnlib.arm_model.ArmKinematics`, formerly defined here with layout
  ``(T, 2, C)``; now ``(node, T, C)`` as everywhere in the package);
* :func:`wsnlib.sim.radio_links.antenna_positions` — where the radio antenna sits.
"""

from __future__ import annotations

from wsnlib.arm_model import ArmKinematics  # noqa: F401
from wsnlib.sim.arm_motion import (  # noqa: F401
    ArmMotion,
    arc,
    concatenate,
    direction_orientation,
    hold,
    jittered_direction,
    movement,
    posture_orientation,
    rotate_to,
    transition,
)
from wsnlib.sim.body_solids import Solid, body_solids, chord_length  # noqa: F401
from wsnlib.sim.users import (  # noqa: F401
    ANCHOR_AXES,
    REFERENCE_HEIGHT_M,
    SHOULDER_HEIGHT_FRACTION,
    BodyShape,
    User,
    make_users,
    nominal_anchor_positions,
    paper_user,
    user_from_height,
)

# The testbed of paper 002 (names, Table 1, postures, movements) lives in wsnlib.testbed, which
# the file formats read too; re-exported here for the simulators and for users' scripts.
from wsnlib.testbed import (  # noqa: F401
    ANCHOR_NAMES,
    ANCHOR_WORN,
    MOVEMENTS,
    PAPER_TARGET_DISTANCES_M,
    POSTURE_DIRECTIONS,
    POSTURES,
    TABLE1_POSITIONS_CM,
    TARGET_NAMES,
    TRANSITION_LABEL,
    posture_direction,
)


def antenna_positions(kin, user, standoff_m: float = 0.01):
    """Moved to :func:`wsnlib.sim.radio_links.antenna_positions` (layout ``(2, T, 3)``)."""
    from wsnlib.sim.radio_links import antenna_positions as _antenna_positions

    return _antenna_positions(kin, user, standoff_m)
