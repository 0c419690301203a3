"""Paper 002's testbed as drawn by wsnlib.plotting.testbed (the anchor layout, the paper's Fig. 4)."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from wsnlib import plotting  # noqa: E402


def test_anchor_layout_numbers_the_anchors_as_the_tables_and_places_them_at_the_users_sites():
    from wsnlib.sim.body import user_from_height

    user = user_from_height("U", 1.62)
    fig = plotting.plot_anchor_layout(user)
    front, side, top = fig.axes
    numbers = {ax: sorted(t.get_text() for t in ax.texts if t.get_text().isdigit()) for ax in fig.axes}
    assert numbers[front] == numbers[side] == ["1", "4", "6", "7"]          # worn: A1, A4, A6, A7
    assert numbers[top] == ["2", "3", "5"]                                  # room: A2, A3, A5
    label = {t.get_text(): t.xy for t in top.texts if t.get_text().isdigit()}
    np.testing.assert_allclose(label["3"], user.anchor_positions_m[2, :2])  # floor plan: (x, y)
    label = {t.get_text(): t.xy for t in side.texts if t.get_text().isdigit()}
    np.testing.assert_allclose(label["7"], user.anchor_positions_m[6, 1:])  # side view: (y, z)
    assert front.xaxis_inverted() and not top.xaxis_inverted()              # seen from the front / above
    heights = sorted(t.get_text() for t in top.texts if t.get_text().endswith("m high"))
    assert heights == ["0.75 m high", "1.20 m high", "1.80 m high"]         # above the floor, not the shoulder
    assert min(size for _, size in plotting.effective_font_sizes(fig)) >= plotting.MIN_FONT_PT
    plt.close(fig)
