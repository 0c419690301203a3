"""The testbed of paper 002 (Giuberti et al.): names, Table 1, postures and movements.

Constants shared by the simulators (:mod:`wsnlib.sim`), the file formats (:mod:`wsnlib.io.rss`,
:mod:`wsnlib.io.accel`) and the studies, so that a file format never has to import a
simulator.  Positions and directions are in the shoulder frame of :mod:`wsnlib.sim.body`
(origin at the right shoulder joint, x to the user's right, y forward, z up), Table 1 in
centimetres as printed, distances in metres.  Where a comment says "module docstring", it is
:mod:`wsnlib.sim.body`'s (P5's entries, the posture directions).
"""

from __future__ import annotations

import numpy as np

from wsnlib import fixed_order

#: Posture names (paper 002, Table 1), in training order.
POSTURES: tuple[str, ...] = ("P1", "P2", "P3", "P4", "P5")

#: Target names, in the order of every target axis in this package's RSS code.
TARGET_NAMES: tuple[str, str] = ("T1", "T2")

#: Anchor names, in the order of every anchor axis (A1 … A7 as in paper 002, Fig. 4).
ANCHOR_NAMES: tuple[str, ...] = ("A1", "A2", "A3", "A4", "A5", "A6", "A7")

#: Which anchors are worn on the body (paper 002, Fig. 4 caption: A1, A4, A6, A7).
ANCHOR_WORN: dict[str, bool] = {"A1": True, "A2": False, "A3": False, "A4": True, "A5": False, "A6": True, "A7": True}

#: Paper 002, Table 1: fingerprint positions (cm) relative to the shoulder, per posture,
#: ``{posture: ((x, y, z) of T1, (x, y, z) of T2)}``.  Verbatim, including P5's entries that
#: no straight arm fits (module docstring).
TABLE1_POSITIONS_CM: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "P1": ((0.0, 0.0, -15.0), (0.0, 0.0, -42.5)),
    "P2": ((0.0, 0.0, 15.0), (0.0, 0.0, 42.5)),
    "P3": ((0.0, 15.0, 0.0), (0.0, 42.5, 0.0)),
    "P4": ((15.0, 0.0, 0.0), (42.5, 0.0, 0.0)),
    "P5": ((-11.0, 11.0, 0.0), (-34.0, 21.0, 0.0)),
}

#: Target distances from the shoulder (m) of paper 002's user (Table 1, P1–P4).
PAPER_TARGET_DISTANCES_M: tuple[float, float] = (0.15, 0.425)


def _p5_direction() -> np.ndarray:
    d = np.array(PAPER_TARGET_DISTANCES_M)
    pts = np.array(TABLE1_POSITIONS_CM["P5"]) / 100.0
    u = d[0] * pts[0] + d[1] * pts[1]  # least squares: minimise Σ |d_i u − p_i|², |u| = 1
    return u / fixed_order.norm(u)


#: Unit arm direction of each posture in the shoulder frame (module docstring).
POSTURE_DIRECTIONS: dict[str, np.ndarray] = {"P1": np.array([0.0, 0.0, -1.0]), "P2": np.array([0.0, 0.0, 1.0]),
                                              "P3": np.array([0.0, 1.0, 0.0]), "P4": np.array([1.0, 0.0, 0.0]),
                                              "P5": _p5_direction()}
for _u in POSTURE_DIRECTIONS.values():
    _u.setflags(write=False)

#: The paper's four transitional movements (Sec. 4.1, Fig. 5): name → postures visited.
MOVEMENTS: dict[str, tuple[str, ...]] = {"lower_P2_P3_P1": ("P2", "P3", "P1"),
                                         "horizontal_P4_P3_P5": ("P4", "P3", "P5"),
                                         "raise_P1_P3": ("P1", "P3"), "horizontal_P3_P4": ("P3", "P4")}

#: Label of the unrecorded arm moves between postures in a session.
TRANSITION_LABEL = "transition"


def posture_direction(posture: str) -> np.ndarray:
    """Unit arm direction (3,) of ``posture`` ("P1" … "P5") in the shoulder frame."""
    try:
        return POSTURE_DIRECTIONS[posture].copy()
    except KeyError:
        raise ValueError(f"posture must be one of {POSTURES}, got {posture!r}") from None
