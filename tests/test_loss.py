import numpy as np
import pytest

from wsnlib import loss

_ONES = np.ones(3, dtype=bool)

# ------------------------------------------------------------------ packets ↔ samples


def test_packets_to_samples_repeats_each_flag():
    packets = np.array([True, False, True])
    samples = loss.packets_to_samples(packets, samples_per_packet=2)
    assert samples.tolist() == [True, True, False, False, True, True]


def test_packets_to_samples_partial_last_packet_and_batch():
    packets = np.array([[True, True, False], [False, True, True]])
    samples = loss.packets_to_samples(packets, samples_per_packet=6, n_samples=14)
    assert samples.shape == (2, 14)
    assert samples[0].tolist() == [True] * 12 + [False] * 2
    assert samples[1].tolist() == [False] * 6 + [True] * 8
    assert loss.n_packets_for(14, 6) == 3
    assert loss.n_packets_for(12, 6) == 2
    assert loss.n_packets_for(0, 6) == 0


@pytest.mark.parametrize("n_samples", [11, 19, 5])
def test_packets_to_samples_rejects_wrong_packet_count(n_samples):
    with pytest.raises(ValueError, match="needs"):
        loss.packets_to_samples(np.ones(3, dtype=bool), 6, n_samples=n_samples)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"packet_received": np.ones(3)}, "boolean"),
        ({"packet_received": _ONES, "samples_per_packet": 0}, "samples_per_packet"),
        ({"packet_received": _ONES, "samples_per_packet": 2.5}, "samples_per_packet"),
        ({"packet_received": np.ones(3, dtype=bool), "n_samples": -1}, "n_samples"),
        ({"packet_received": np.bool_(True)}, "dimension"),
    ],
)
def test_packets_to_samples_bad_inputs(kwargs, match):
    with pytest.raises(ValueError, match=match):
        loss.packets_to_samples(**kwargs)


# ------------------------------------------------------------------ bursts


def test_burst_loss_placement_and_end_cut():
    mask = loss.burst_loss(10, 3, 4)
    assert np.flatnonzero(~mask).tolist() == [3, 4, 5, 6]
    assert np.flatnonzero(~loss.burst_loss(10, 8, 4)).tolist() == [8, 9]
    assert loss.burst_loss(10, 10, 4).all()
    assert loss.burst_loss(10, 0, 0).all()
    assert not loss.burst_loss(5, 0, 5).any()


def test_burst_mask_paper_case_next_and_exact():
    n = 300
    nxt = loss.burst_mask(n, 80, 4)
    assert np.flatnonzero(~nxt).tolist() == list(range(84, 108))
    # "next" is the same as building the burst on the packet grid.
    packets = loss.burst_loss(loss.n_packets_for(n), 14, 4)
    assert np.array_equal(nxt, loss.packets_to_samples(packets, 6, n))
    exact = loss.burst_mask(n, 80, 4, align="exact")
    assert np.flatnonzero(~exact).tolist() == list(range(80, 104))
    assert loss.lost_run_length(exact).max() == 24
    # On a packet boundary both alignments agree.
    assert np.array_equal(loss.burst_mask(n, 78, 4), loss.burst_mask(n, 78, 4, align="exact"))


def test_burst_mask_at_start_and_end():
    start = loss.burst_mask(30, 0, 2)
    assert np.flatnonzero(~start).tolist() == list(range(12))
    end = loss.burst_mask(30, 25, 3, align="exact")
    assert np.flatnonzero(~end).tolist() == list(range(25, 30))
    assert loss.burst_mask(30, 25, 3).all()  # next boundary (30) is past the end
    assert loss.burst_mask(30, 30, 3, align="exact").all()


@pytest.mark.parametrize(
    "args, kwargs, match",
    [
        ((30, 31, 1), {}, "start_sample"),
        ((30, -1, 1), {}, "start_sample"),
        ((30, 5, -1), {}, "n_packets"),
        ((30, 5, 1, 0), {}, "samples_per_packet"),
        ((30, 5, 1), {"align": "previous"}, "align"),
        ((30.0, 5, 1), {}, "n_samples"),
    ],
)
def test_burst_mask_bad_inputs(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        loss.burst_mask(*args, **kwargs)


def test_burst_loss_bad_inputs():
    with pytest.raises(ValueError, match="start_packet"):
        loss.burst_loss(5, 6, 1)
    with pytest.raises(ValueError, match="n_lost"):
        loss.burst_loss(5, 1, -2)


# ------------------------------------------------------------------ random models


@pytest.mark.parametrize("loss_rate, mean_burst", [(0.1, 3.0), (0.3, 1.5), (0.05, 1.0), (0.5, 8.0)])
def test_gilbert_elliott_matches_rate_and_mean_burst(loss_rate, mean_burst):
    rng = np.random.default_rng(2024)
    mask = loss.gilbert_elliott(10_000, loss_rate, mean_burst, rng=rng, shape=(40,))
    assert mask.shape == (40, 10_000)
    # 400k packets; bursty losses inflate the variance, tolerance ~ 5 standard errors.
    assert 1.0 - mask.mean() == pytest.approx(loss_rate, rel=0.05)
    bursts = loss.burst_lengths(mask)
    assert bursts.mean() == pytest.approx(mean_burst, rel=0.05)
    # Stationary start: the first packet is lost with probability loss_rate.
    first = loss.gilbert_elliott(1, loss_rate, mean_burst, rng=rng, shape=(20_000,))
    assert 1.0 - first.mean() == pytest.approx(loss_rate, abs=0.02)


def test_gilbert_elliott_determinism_and_edges():
    a = loss.gilbert_elliott(500, 0.2, 4.0, rng=np.random.default_rng(7), shape=(3, 2))
    b = loss.gilbert_elliott(500, 0.2, 4.0, rng=np.random.default_rng(7), shape=(3, 2))
    c = loss.gilbert_elliott(500, 0.2, 4.0, rng=np.random.default_rng(8), shape=(3, 2))
    assert a.shape == (3, 2, 500)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert loss.gilbert_elliott(100, 0.0, 3.0, rng=np.random.default_rng(0)).all()
    assert loss.gilbert_elliott(0, 0.2, 3.0, rng=np.random.default_rng(0)).shape == (0,)
    p_gb, p_bg = loss.gilbert_elliott_probabilities(0.2, 4.0)
    assert p_bg == 0.25 and p_gb / (p_gb + p_bg) == pytest.approx(0.2)


@pytest.mark.parametrize("loss_rate, mean_burst", [(0.1, 3.0), (0.0, 2.0), (0.5, 1.0), (0.6, 4.0), (0.3, 1.2)])
def test_gilbert_elliott_is_the_markov_chain_step_by_step(loss_rate, mean_burst):
    # The vectorised chain against the chain written packet by packet on the same uniform draws
    # (p_GB > p_BG in (0.6, 4.0): draws between them set Bad, not Good).
    mask = loss.gilbert_elliott(3000, loss_rate, mean_burst, rng=np.random.default_rng(5), shape=(4, 3))
    p_gb, p_bg = loss.gilbert_elliott_probabilities(loss_rate, mean_burst)
    u = np.random.default_rng(5).random((4, 3, 3000))
    lost = np.empty(u.shape, dtype=bool)
    lost[..., 0] = u[..., 0] < p_gb / (p_gb + p_bg)
    for k in range(1, u.shape[-1]):
        lost[..., k] = np.where(lost[..., k - 1], u[..., k] >= p_bg, u[..., k] < p_gb)
    assert np.array_equal(mask, ~lost)


@pytest.mark.parametrize(
    "loss_rate, mean_burst, match",
    [
        (1.0, 3.0, "loss_rate"),
        (-0.1, 3.0, "loss_rate"),
        (0.2, 0.5, "mean_burst"),
        (0.2, float("nan"), "mean_burst"),
        (0.6, 1.0, "loss_rate"),  # needs mean_burst >= 1.5
        ("a", 2.0, "loss_rate"),
    ],
)
def test_gilbert_elliott_bad_parameters(loss_rate, mean_burst, match):
    with pytest.raises(ValueError, match=match):
        loss.gilbert_elliott(10, loss_rate, mean_burst, rng=np.random.default_rng(0))


def test_random_models_require_a_generator():
    with pytest.raises(ValueError, match="rng"):
        loss.gilbert_elliott(10, 0.1, 2.0, rng=np.random.RandomState(0))
    with pytest.raises(ValueError, match="rng"):
        loss.gilbert_elliott(10, 0.1, 2.0, rng=None)
    with pytest.raises(ValueError, match="shape"):
        loss.gilbert_elliott(10, 0.1, 2.0, rng=np.random.default_rng(0), shape=(-1,))


# ------------------------------------------------------------------ run lengths


def test_last_received_index_with_and_without_backfill():
    received = np.array([[False, False, True, False, True, False], [False] * 6])
    assert loss.last_received_index(received).tolist() == [[-1, -1, 2, 2, 4, 4], [-1] * 6]
    assert loss.last_received_index(received, backfill=True).tolist() == [[2, 2, 2, 2, 4, 4], [0] * 6]


def test_lost_run_length_table():
    received = np.array([False, False, True, False, False, False, True, True, False])
    assert loss.lost_run_length(received).tolist() == [1, 2, 0, 1, 2, 3, 0, 0, 1]


def test_lost_run_length_edges_and_batch():
    batch = np.array([[True] * 5, [False] * 5, [True, True, True, False, False]])
    lam = loss.lost_run_length(batch)
    assert lam.dtype.kind == "i"
    assert lam.tolist() == [[0] * 5, [1, 2, 3, 4, 5], [0, 0, 0, 1, 2]]
    assert loss.lost_run_length(np.zeros((2, 0), dtype=bool)).shape == (2, 0)
    assert loss.burst_lengths(batch).tolist() == [5, 2]
    assert loss.burst_lengths(np.ones(4, dtype=bool)).size == 0
    with pytest.raises(ValueError, match="boolean"):
        loss.lost_run_length(np.array([1, 0, 1]))


def test_lost_run_length_matches_loop(rng):
    received = rng.random((4, 200)) > 0.3
    expected = np.zeros(received.shape, dtype=int)
    for row in range(4):
        run = 0
        for k in range(200):
            run = 0 if received[row, k] else run + 1
            expected[row, k] = run
    assert np.array_equal(loss.lost_run_length(received), expected)


def test_hold_last_forward_fills_and_backfills_the_start():
    values = np.arange(6.0)[:, None] * np.ones((1, 2))
    received = np.array([False, True, False, False, True, False])
    held = loss.hold_last(values, received)
    np.testing.assert_array_equal(held[:, 0], [1, 1, 1, 1, 4, 4])
    # a batch of masks over one sequence
    masks = np.stack([received, np.ones(6, bool)])
    assert loss.hold_last(values, masks).shape == (2, 6, 2)
    np.testing.assert_array_equal(loss.hold_last(values, masks)[1], values)
    with np.testing.assert_raises(ValueError):
        loss.hold_last(values, np.zeros(6, bool))
    with np.testing.assert_raises(ValueError):
        loss.hold_last(values, received[:5])


def test_burst_train_places_whole_packet_bursts_periodically():
    received, ends = loss.burst_train(300, 10, 100, 2)
    assert ends.tolist() == [24, 126, 222]      # bursts start at 12, 114, 210 (packet grid)
    assert (~received).sum() == 3 * 12
    assert all(received[e] and not received[e - 1] for e in ends)
    with np.testing.assert_raises(ValueError):
        loss.burst_train(300, 10, 12, 2)


# --- LossProfile: one type for the Monte Carlo trials and the loss study ------------------------


def test_loss_profile_masks_are_the_loss_models():
    fs, n = 50.0, 700
    assert loss.LossProfile.none().mask(n, fs, None, shape=(2, 3)).all()
    single = loss.LossProfile.burst(80 / fs, 4)
    np.testing.assert_array_equal(single.mask(n, fs, None), loss.burst_mask(n, 80, 4))
    assert single.name == "burst 4 packets" and single.mask(n, fs, None, shape=(2,)).shape == (2, n)
    train = loss.LossProfile.burst(4.0, 4, period_s=8.0, name="paper burst")
    np.testing.assert_array_equal(train.mask(n, fs, None), loss.burst_train(n, 200, 400, 4)[0])
    ge = loss.LossProfile.gilbert_elliott(0.1, samples_per_packet=12)
    assert ge.name == "GE 10 %"
    expected = loss.packets_to_samples(loss.gilbert_elliott(loss.n_packets_for(n, 12), 0.1, 3.0,
                                                            rng=np.random.default_rng(4), shape=(3,)), 12, n)
    np.testing.assert_array_equal(ge.mask(n, fs, np.random.default_rng(4), shape=(3,)), expected)
    assert loss.LossProfile.gilbert_elliott(0.0).model == "none"
    with pytest.raises(ValueError, match="model"):
        loss.LossProfile("x", "bernoulli")
