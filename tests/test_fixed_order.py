"""wsnlib.fixed_order: sums in index order, the same bits whatever the batch."""

import numpy as np
import pytest

from wsnlib import fixed_order


def test_dot_adds_in_index_order_and_does_not_depend_on_the_batch(rng):
    a, b = rng.normal(size=(50, 7)), rng.normal(size=(50, 7))
    expected = a[:, 0] * b[:, 0]
    for i in range(1, 7):
        expected = expected + a[:, i] * b[:, i]
    np.testing.assert_array_equal(fixed_order.dot(a, b), expected)
    np.testing.assert_array_equal(fixed_order.dot(a[3], b[3]), expected[3])  # one row alone: same bits
    np.testing.assert_allclose(fixed_order.norm(a), np.linalg.norm(a, axis=-1), rtol=1e-14)


def test_matmul_equals_the_matrix_product_and_each_row_is_independent_of_the_others(rng):
    a, b = rng.normal(size=(4, 30, 6)), rng.normal(size=(6, 9))
    out = fixed_order.matmul(a, b)
    np.testing.assert_allclose(out, a @ b, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(fixed_order.matmul(a[2, 5:6], b), out[2, 5:6])
    with pytest.raises(ValueError, match="matmul needs"):
        fixed_order.matmul(a, b.T)
