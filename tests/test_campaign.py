import numpy as np
import pytest

from wsnlib.sim.campaign import simulate_campaign


def test_campaign_has_every_user_and_session_and_is_seeded():
    first = simulate_campaign(2, rng=np.random.default_rng(3), hold_s=2.0, static_hold_s=1.0, dynamic=False)
    again = simulate_campaign(2, rng=np.random.default_rng(3), hold_s=2.0, static_hold_s=1.0, dynamic=False)
    assert set(first.rss["user"]) == {"U1", "U2"}
    assert set(first.rss["session"]) == {"training", "online_static"}
    assert first.rss.equals(again.rss)
    assert len(first.users) == len(first.online_users) == 2
    with pytest.raises(ValueError, match="n_users"):
        simulate_campaign(0, rng=np.random.default_rng(3))
