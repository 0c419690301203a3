import hashlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from wsnlib import plotting  # noqa: E402


def _draw_and_save(name):
    plotting.use_style()
    fig, ax = plt.subplots()
    t = np.arange(50) / 50.0
    received = np.ones(50, bool)
    received[10:16] = False
    plotting.plot_angle_traces(t, {"truth": t * 10, "data fusion": t * 9}, ax=ax,
                               loss_spans=plotting.loss_spans(t, received))
    written = plotting.savefig(fig, name)
    plt.close(fig)
    return {p.suffix: hashlib.sha256(p.read_bytes()).hexdigest() for p in written}


def test_savefig_is_byte_reproducible(output_dir):
    first = _draw_and_save("repro")
    second = _draw_and_save("repro")
    assert set(first) == {".png", ".pdf"}
    assert first == second
    assert (output_dir / "figures" / "repro.png").exists()


def test_savefig_rejects_path_like_names(output_dir):
    fig = plt.figure()
    with pytest.raises(ValueError, match="name"):
        plotting.savefig(fig, "../escape")
    with pytest.raises(ValueError, match="formats"):
        plotting.savefig(fig, "ok", formats=("jpg",))
    plt.close(fig)


def test_loss_spans_cover_start_and_end():
    t = np.arange(10) * 0.1
    received = np.array([0, 0, 1, 1, 0, 1, 1, 1, 0, 0], dtype=bool)
    spans = np.array(plotting.loss_spans(t, received))
    np.testing.assert_allclose(spans, [(0.0, 0.2), (0.4, 0.5), (0.8, 1.0)])
    assert plotting.loss_spans(t, np.ones(10, bool)) == []


def test_import_changes_no_global_style():
    import importlib

    before = dict(matplotlib.rcParams)
    importlib.reload(plotting)
    assert dict(matplotlib.rcParams) == before


def test_heatmap_and_pareto_draw_and_validate(output_dir):
    fig, (ax_a, ax_b) = plt.subplots(1, 2)
    plotting.plot_heatmap(np.arange(6.0).reshape(2, 3), [1, 2], [1, 2, 3], ax=ax_a)
    with pytest.raises(ValueError, match="shape"):
        plotting.plot_heatmap(np.zeros((3, 2)), [1, 2], [1, 2, 3], ax=ax_a)
    x = np.array([1.0, 2.0, 3.0])
    y = np.array([30.0, 20.0, 25.0])
    plotting.plot_pareto(x, y, groups=["a", "b", "b"], front=[True, True, False], knee=1,
                         references={"data fusion": (4.0, 10.0)}, ax=ax_b)
    assert len(ax_b.collections) == 4   # two groups, the knee, one reference
    plt.close(fig)
