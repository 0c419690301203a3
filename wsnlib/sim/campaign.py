"""A whole measurement campaign of paper 002 (Sec. 4.1), simulated: users × sessions.

For each of ``n_users`` simulated users (:func:`wsnlib.sim.body.make_users`): a training
session (five postures held ``hold_s`` each), then, on a different "day" (re-donned t-shirt,
moved anchors, new fading: :meth:`wsnlib.sim.body.User.moved`), an online static session
(the five postures again) and an online dynamic session (the four transitional movements,
twice).  All from one seeded generator, in a fixed order, so a seed fixes the campaign.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from wsnlib.sim.body import User, make_users
from wsnlib.sim.radio import concat_rss, online_dynamic_session, online_static_session, training_session


@dataclass(frozen=True)
class Campaign:
    """Simulated RSS campaign.

    Attributes
    ----------
    rss : pandas.DataFrame
        Long RSS table (schema of :mod:`wsnlib.rss`), every user and session.
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
