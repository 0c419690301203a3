"""Fixtures of the simulator tests that the library itself does not need."""

import pandas as pd

from wsnlib.arm_model import UPPER_ARM_FRACTION
from wsnlib.sim.body import BodyShape, User, nominal_anchor_positions
from wsnlib.testbed import ANCHOR_NAMES, PAPER_TARGET_DISTANCES_M


def paper_user(name: str = "paper", *, environment_seed: int = 0) -> User:
    """Paper 002's user: T1 at 15 cm and T2 at 42.5 cm (Table 1), upper arm 0.30 m, forearm 0.25 m.

    Height 1.62 m (Winter's 0.186 H = 0.30 m); anchors at their nominal sites, no jitter.
    """
    height = 0.30 / UPPER_ARM_FRACTION
    return User(
        name=name,
        height_m=height,
        upper_arm_m=0.30,
        forearm_m=0.25,
        target_distances_m=PAPER_TARGET_DISTANCES_M,
        anchor_positions_m=nominal_anchor_positions(height),
        body=BodyShape.from_height(height),
        environment_seed=environment_seed,
    )


def posture_mean_rss(df: pd.DataFrame, target: str = "T1") -> pd.DataFrame:
    """Mean RSS (dBm) per anchor (rows) and label (columns) of one target — a quick look table."""
    sub = df[df["target"] == target]
    table = sub.pivot_table(index="anchor", columns="label", values="rss_dbm", aggfunc="mean")
    return table.reindex(index=[a for a in ANCHOR_NAMES if a in table.index])
