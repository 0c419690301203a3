"""Tests for wsnlib.quaternion: scipy as the reference, hypothesis for invariants."""

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation, Slerp

from wsnlib import quaternion as Q

# ---------------------------------------------------------------- strategies

_finite = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)
_raw_quat = arrays(float, 4, elements=_finite).filter(lambda v: np.linalg.norm(v) > 1e-3)
unit_quats = _raw_quat.map(lambda v: v / np.linalg.norm(v))
vectors = arrays(float, 3, elements=st.floats(-10.0, 10.0, allow_nan=False))
mus = st.floats(0.0, 1.0, allow_nan=False)


def random_quats(rng, shape):
    q = rng.normal(size=tuple(shape) + (4,))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def same_rotation(q_a, q_b, atol=1e-12):
    """q and -q are the same rotation: compare up to sign, per quaternion."""
    sign = np.where(np.sum(q_a * q_b, axis=-1, keepdims=True) < 0.0, -1.0, 1.0)
    np.testing.assert_allclose(q_a, sign * q_b, atol=atol, rtol=0)


# ---------------------------------------------------------------- scipy round trips


def test_scipy_round_trip(rng):
    q = random_quats(rng, (5, 7))
    back = Q.from_scipy(Q.to_scipy(q.reshape(-1, 4))).reshape(q.shape)
    same_rotation(back, q)


def test_scalar_first_layout():
    # 90° about z: scipy stores [x, y, z, w]; wsnlib [w, x, y, z].
    q = Q.from_scipy(Rotation.from_euler("z", 90, degrees=True))
    same_rotation(q, np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)]))
    np.testing.assert_allclose(Q.rotate(q, [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0], atol=1e-15)


def test_from_scipy_to_scipy(rng):
    r = Rotation.random(20, rng=rng)
    np.testing.assert_allclose(
        Q.to_scipy(Q.from_scipy(r)).as_matrix(), r.as_matrix(), atol=1e-12
    )


# ---------------------------------------------------------------- products and rotations


def test_multiply_matches_scipy_composition(rng):
    p, q = random_quats(rng, (30,)), random_quats(rng, (30,))
    # p ⊗ q applies q first: scipy's r_p * r_q.
    expected = Q.from_scipy(Q.to_scipy(p) * Q.to_scipy(q))
    same_rotation(Q.multiply(p, q), expected)


def test_multiply_broadcasts(rng):
    p, q = random_quats(rng, (4, 1)), random_quats(rng, (1, 6))
    out = Q.multiply(p, q)
    assert out.shape == (4, 6, 4)
    np.testing.assert_allclose(out[2, 3], Q.multiply(p[2, 0], q[0, 3]), atol=1e-15)


def test_rotate_matches_scipy_apply(rng):
    q = random_quats(rng, (40,))
    v = rng.normal(size=(40, 3))
    np.testing.assert_allclose(Q.rotate(q, v), Q.to_scipy(q).apply(v), atol=1e-12)
    np.testing.assert_allclose(
        Q.rotate_inverse(q, v), Q.to_scipy(q).apply(v, inverse=True), atol=1e-12
    )


def test_rotate_inverse_undoes_rotate(rng):
    q = random_quats(rng, (10,))
    v = rng.normal(size=(10, 3))
    np.testing.assert_allclose(Q.rotate_inverse(q, Q.rotate(q, v)), v, atol=1e-12)


def test_angle_between_matches_scipy_magnitude(rng):
    q_a, q_b = random_quats(rng, (50,)), random_quats(rng, (50,))
    expected = (Q.to_scipy(q_a).inv() * Q.to_scipy(q_b)).magnitude()
    np.testing.assert_allclose(Q.angle_between(q_a, q_b), expected, atol=1e-12)


def test_angle_between_small_angles_accurate():
    angle = 1e-9
    q = Q.from_axis_angle([0.0, 1.0, 0.0], angle)
    assert Q.angle_between(Q.identity(), q) == pytest.approx(angle, rel=1e-9)


def test_from_axis_angle_and_rotation_vector_match_scipy(rng):
    rotvec = rng.normal(size=(20, 3))
    same_rotation(Q.from_rotation_vector(rotvec), Q.from_scipy(Rotation.from_rotvec(rotvec)))
    angle = np.linalg.norm(rotvec, axis=-1)
    same_rotation(Q.from_axis_angle(rotvec, angle), Q.from_rotation_vector(rotvec))
    np.testing.assert_array_equal(Q.from_rotation_vector(np.zeros(3)), [1.0, 0.0, 0.0, 0.0])


def test_identity_conjugate_canonical(rng):
    assert Q.identity((2, 3)).shape == (2, 3, 4)
    q = random_quats(rng, (10,))
    same_rotation(Q.multiply(q, Q.conjugate(q)), Q.identity((10,)))
    c = Q.canonical(q)
    assert np.all(c[:, 0] >= 0.0)
    same_rotation(c, q)


# ---------------------------------------------------------------- slerp


@pytest.mark.parametrize("mu", [0.0, 0.1, 0.5, 0.77, 1.0])
def test_slerp_matches_scipy(rng, mu):
    q_a, q_b = random_quats(rng, (25,)), random_quats(rng, (25,))
    out = Q.slerp(q_a, q_b, mu)
    for i in range(len(q_a)):
        ref = Slerp([0.0, 1.0], Q.to_scipy(np.stack([q_a[i], q_b[i]])))([mu])
        same_rotation(out[i], Q.from_scipy(ref)[0])


def test_slerp_per_sample_mu_and_batches(rng):
    q_a, q_b = random_quats(rng, (3, 8)), random_quats(rng, (3, 8))
    mu = rng.random((3, 8))
    out = Q.slerp(q_a, q_b, mu)
    assert out.shape == (3, 8, 4)
    for i in range(3):
        for j in range(8):
            ref = Slerp([0.0, 1.0], Q.to_scipy(np.stack([q_a[i, j], q_b[i, j]])))([mu[i, j]])
            same_rotation(out[i, j], Q.from_scipy(ref)[0])


def test_slerp_mu_broadcasts_over_a_batch_of_masks(rng):
    q_a, q_b = random_quats(rng, (8,)), random_quats(rng, (8,))
    mu = rng.random((5, 8))
    out = Q.slerp(q_a, q_b, mu)
    assert out.shape == (5, 8, 4)
    np.testing.assert_allclose(out[3], Q.slerp(q_a, q_b, mu[3]), atol=1e-15)


def test_slerp_takes_shortest_path(rng):
    q_a, q_b = random_quats(rng, (20,)), random_quats(rng, (20,))
    mu = rng.random(20)
    np.testing.assert_allclose(Q.slerp(q_a, -q_b, mu), Q.slerp(q_a, q_b, mu), atol=1e-12)
    # Half way lies at half the rotation angle.
    half = Q.slerp(q_a, q_b, 0.5)
    np.testing.assert_allclose(
        Q.angle_between(q_a, half), 0.5 * Q.angle_between(q_a, q_b), atol=1e-12
    )


@pytest.mark.parametrize("gap", [0.0, 1e-15, 1e-9, 1e-7, 2e-6])
def test_slerp_near_identical_quaternions_finite(rng, gap):
    q_a = random_quats(rng, (6,))
    q_b = Q.multiply(q_a, Q.from_axis_angle([0.3, -1.0, 0.2], gap))
    mu = np.linspace(0.0, 1.0, 6)
    out = Q.slerp(q_a, q_b, mu)
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(np.linalg.norm(out, axis=-1), 1.0, atol=1e-15)
    np.testing.assert_allclose(Q.angle_between(q_a, out), mu * gap, atol=1e-12)


# ---------------------------------------------------------------- hypothesis invariants


@settings(max_examples=60, deadline=None)
@given(unit_quats, unit_quats)
def test_product_is_unit(p, q):
    assert np.linalg.norm(Q.multiply(p, q)) == pytest.approx(1.0, abs=1e-12)


@settings(max_examples=60, deadline=None)
@given(unit_quats, unit_quats, mus)
def test_slerp_is_unit(q_a, q_b, mu):
    assert np.linalg.norm(Q.slerp(q_a, q_b, mu)) == pytest.approx(1.0, abs=1e-12)


@settings(max_examples=60, deadline=None)
@given(unit_quats, unit_quats)
@example(Q.normalize(np.array([2.0**-24, -(2.0**-24), 1.0, 0.0])), Q.normalize(np.array([-1.0, -1.0, 0.0, -1.0])))
def test_slerp_endpoints(q_a, q_b):
    np.testing.assert_allclose(Q.slerp(q_a, q_b, 0.0), q_a, atol=1e-12)
    end = Q.slerp(q_a, q_b, 1.0)
    dot = float(np.sum(q_a * q_b))
    # the shorter way round: q_b or −q_b; with q_a ⟂ q_b (a dot within rounding of 0) both are
    ends = [q_b, -q_b] if abs(dot) <= 1e-12 else [q_b if dot >= 0.0 else -q_b]
    assert any(np.allclose(end, want, rtol=0.0, atol=1e-12) for want in ends), (end, q_b, dot)


@settings(max_examples=60, deadline=None)
@given(unit_quats, unit_quats, vectors)
def test_sign_does_not_change_the_rotation(q_a, q_b, v):
    np.testing.assert_allclose(Q.rotate(-q_a, v), Q.rotate(q_a, v), atol=1e-12)
    angle = Q.angle_between(q_a, q_b)
    assert Q.angle_between(-q_a, q_b) == pytest.approx(angle, abs=1e-12)
    assert Q.angle_between(q_a, -q_b) == pytest.approx(angle, abs=1e-12)
    assert 0.0 <= angle <= np.pi + 1e-12


@settings(max_examples=60, deadline=None)
@given(_raw_quat)
def test_normalize_gives_unit(q):
    assert np.linalg.norm(Q.normalize(q)) == pytest.approx(1.0, abs=1e-15)


# ---------------------------------------------------------------- errors


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: Q.normalize([0.0, 0.0, 0.0, 0.0]), "q"),
        (lambda: Q.normalize([1.0, np.nan, 0.0, 0.0]), "q"),
        (lambda: Q.normalize([1.0, 0.0, 0.0]), "q"),
        (lambda: Q.slerp([0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], 0.5), "q_a"),
        (lambda: Q.slerp([1.0, 0.0, 0.0, 0.0], [np.inf, 0.0, 0.0, 0.0], 0.5), "q_b"),
        (lambda: Q.slerp([1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], 1.5), "mu"),
        (lambda: Q.slerp([1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], -0.1), "mu"),
        (lambda: Q.slerp([1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], np.nan), "mu"),
        (lambda: Q.from_axis_angle([0.0, 0.0, 0.0], 1.0), "axis"),
        (lambda: Q.to_scipy([1.0, 0.0]), "q"),
    ],
)
def test_errors_name_the_argument(call, name):
    with pytest.raises(ValueError, match=rf"\b{name}\b"):
        call()


def test_multiply_and_normalize_are_numpys_bits(rng):
    """The compiled Hamilton product and normalisation: numpy's expressions, bit for bit, broadcasting,
    strided and read-only operands included."""
    def numpy_multiply(p, q):
        pw, px, py, pz = np.moveaxis(p, -1, 0)
        qw, qx, qy, qz = np.moveaxis(q, -1, 0)
        return np.stack([pw * qw - px * qx - py * qy - pz * qz, pw * qx + px * qw + py * qz - pz * qy,
                         pw * qy - px * qz + py * qw + pz * qx, pw * qz + px * qy - py * qx + pz * qw], axis=-1)

    p = rng.normal(size=(3, 200, 4)) * 10.0 ** rng.uniform(-5, 5, size=(3, 200, 4))
    q = rng.normal(size=(200, 4))
    ro = np.broadcast_to(q[0], (200, 4))
    for a, b in ((p, q), (q, p), (p[:, ::2], q[::2]), (p[..., ::-1], p), (ro, q), (p[0, 0], q[0]), (p[:, :1], q[None])):
        ours, expected = Q.multiply(a, b), numpy_multiply(np.asarray(a), np.asarray(b))
        assert ours.shape == expected.shape and np.array_equal(ours.view(np.uint64), expected.view(np.uint64))
    for a in (p, p[:, ::3], p[0, 0]):
        expected = a / np.linalg.norm(a, axis=-1)[..., None]
        assert np.array_equal(Q.normalize(a).view(np.uint64), expected.view(np.uint64))
    zero = p.copy()
    zero[2, 17] = 0.0
    with pytest.raises(ValueError, match=r"quat_est has a zero-norm vector at index \(2, 17\)"):
        Q.normalize(zero, "quat_est")
    with pytest.raises(ValueError, match=r"q has a zero-norm vector at index \(\)"):
        Q.normalize(np.zeros(4))


def test_quaternions_with_gaps_are_numpys_bits_and_refuse_inf_and_zero(rng):
    """``as_quat_with_gaps``: gap rows all NaN, the others as given or (``unit``) divided by numpy's norm,
    bit for bit, whatever the input's memory layout (broadcast, strided, Fortran order, a list)."""
    q = rng.normal(size=(300, 4)) * 10.0 ** rng.uniform(-100, 100, size=(300, 1))
    q[rng.random(300) < 0.1, 2] = np.nan
    for value in (q, np.broadcast_to(q, (2, 300, 4)), q[::3], np.asfortranarray(q), q.tolist()):
        expected = np.array(value, dtype=float)
        expected[np.isnan(expected).any(axis=-1)] = np.nan
        assert np.array_equal(Q.as_quat_with_gaps(value, "q").view(np.uint64),
                              np.ascontiguousarray(expected).view(np.uint64))
        unit = expected / np.linalg.norm(expected, axis=-1, keepdims=True)
        assert np.array_equal(Q.as_quat_with_gaps(value, "q", unit=True).view(np.uint64), unit.view(np.uint64))
    for bad, message in (([[np.nan, np.inf, 0, 0]], "contains inf"), ([[0, 0, 0, 0], [1, 0, 0, 0]], "zero quaternion")):
        for unit in (False, True):
            with pytest.raises(ValueError, match=f"quat_ref {message}" if message == "contains inf" else message):
                Q.as_quat_with_gaps(np.array(bad, dtype=float), "quat_ref", unit=unit)
    assert np.isnan(Q.as_quat_with_gaps([[0.0, 0.0, 0.0, np.nan]], "q", unit=True)).all()  # a gap, not a zero
