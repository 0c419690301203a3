"""Davenport, QUEST and SVD single-frame solutions against TRIAD and scipy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from wsnlib import frames
from wsnlib import quaternion as Q
from wsnlib.orientation import triad
from wsnlib.orientation.single_frame import davenport, quest, svd_single_frame


def _exact(n=50, seed=0):
    quat = Q.canonical(Q.from_scipy(Rotation.random(n, random_state=seed)))
    acc = Q.rotate_inverse(quat, frames.gravity_specific_force_enu())
    mag = Q.rotate_inverse(quat, np.broadcast_to(frames.magnetic_field_enu(), (n, 3)))
    return quat, acc, mag


@pytest.mark.parametrize("method", [davenport, quest, svd_single_frame])
def test_exact_data_gives_truth_and_triad(method):
    quat, acc, mag = _exact()
    np.testing.assert_allclose(Q.canonical(method(acc, mag)), quat, atol=1e-9)
    np.testing.assert_allclose(Q.canonical(method(acc, mag)), triad(acc, mag), atol=1e-9)


def test_davenport_equals_svd_on_noisy_data():
    _, acc, mag = _exact(seed=1)
    rng = np.random.default_rng(2)
    acc = acc + rng.normal(0, 1.0, acc.shape)
    mag = mag + rng.normal(0, 5.0, mag.shape)
    for weights in [(1.0, 0.1), (1.0, 1.0)]:
        np.testing.assert_allclose(davenport(acc, mag, weights=weights), svd_single_frame(acc, mag, weights=weights),
                                   atol=1e-9)


@pytest.mark.parametrize("weights", [(1.0, 0.1), (1.0, 1.0), (0.3, 2.0)])
def test_quest_equals_davenport_on_noisy_data(weights):
    _, acc, mag = _exact(n=200, seed=4)
    rng = np.random.default_rng(5)
    acc = acc + rng.normal(0, 1.0, acc.shape)
    mag = mag + rng.normal(0, 5.0, mag.shape)
    np.testing.assert_allclose(quest(acc, mag, weights=weights), davenport(acc, mag, weights=weights), atol=1e-9)


def test_quest_near_180_degrees_uses_sequential_rotations():
    # rotations by 180° (w = 0) and just below: det M → 0 in the original frame
    quat = Q.normalize(np.array([[0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0],
                                 [0.0, 0.6, 0.8, 0.0], [1e-9, 0.6, 0.0, 0.8], [1e-5, 0.0, -0.6, 0.8]]))
    acc = Q.rotate_inverse(quat, frames.gravity_specific_force_enu())
    mag = Q.rotate_inverse(quat, np.broadcast_to(frames.magnetic_field_enu(), (len(quat), 3)))
    assert np.degrees(Q.angle_between(quest(acc, mag), quat)).max() < 1e-9
    assert np.degrees(Q.angle_between(quest(acc, mag), triad(acc, mag))).max() < 1e-9


def test_weights_trade_tilt_against_heading():
    quat, acc, mag = _exact(n=20, seed=3)
    # a field whose dip is off by 20°: TRIAD ignores dip, Wahba with a heavy mag weight tilts
    dip_off = Q.rotate_inverse(quat, frames.magnetic_field_enu(dip_deg=frames.MAGNETIC_DIP_DEG + 20.0))
    tilt_heavy = davenport(acc, dip_off, weights=(1.0, 0.01))
    mag_heavy = davenport(acc, dip_off, weights=(1.0, 1.0))
    assert Q.angle_between(tilt_heavy, quat).max() < Q.angle_between(mag_heavy, quat).min()


def test_shapes_and_errors():
    quat, acc, mag = _exact(n=6)
    assert davenport(acc.reshape(2, 3, 3), mag.reshape(2, 3, 3)).shape == (2, 3, 4)
    assert davenport(acc[0], mag[0]).shape == (4,)
    with pytest.raises(ValueError, match="acc"):
        davenport(np.zeros(3), mag[0])
    with pytest.raises(ValueError, match="weights"):
        davenport(acc, mag, weights=(1.0, -1.0))
    assert quest(acc.reshape(2, 3, 3), mag.reshape(2, 3, 3)).shape == (2, 3, 4)
    assert quest(acc[0], mag[0]).shape == (4,)
    with pytest.raises(ValueError, match="mag"):
        quest(acc[0], np.zeros(3))
