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


def _figure_with_text(width_in, fontsize):
    plotting.use_style()
    fig, ax = plt.subplots(figsize=(width_in, 3))
    ax.plot([0, 1], [0, 1])
    ax.tick_params(labelsize=fontsize)
    ax.set_xlabel("x", fontsize=fontsize)
    ax.text(0.5, 0.5, "note", fontsize=fontsize)
    return fig


def test_effective_font_sizes_shrink_with_a_figure_wider_than_the_notebook():
    narrow = plotting.effective_font_sizes(_figure_with_text(5.0, 9.0))
    assert {text for text, _ in narrow} >= {"x", "note", "0.0", "1.0"}
    assert all(size == pytest.approx(9.0) for _, size in narrow)
    wide = _figure_with_text(15.0, 9.0)
    sizes = dict(plotting.effective_font_sizes(wide))
    width_in = wide.get_tightbbox().width   # the saved image's width (savefig.bbox: tight)
    assert sizes["note"] == pytest.approx(9.0 * plotting.DISPLAY_WIDTH_IN / width_in)
    assert sizes["note"] < 6.0
    # Hidden texts do not count: a turned-off axis has no tick labels to read.
    wide.axes[0].axis("off")
    assert "1.0" not in dict(plotting.effective_font_sizes(wide))
    with pytest.raises(ValueError, match="display_width_in"):
        plotting.effective_font_sizes(wide, display_width_in=0)
    plt.close("all")


def test_savefig_refuses_small_text_in_the_batch_and_warns_interactively(output_dir, monkeypatch):
    small = _figure_with_text(6.0, 6.0)
    monkeypatch.setenv("WSNLIB_BATCH", "1")
    with pytest.raises(ValueError, match=r"'too_small': 14 text\(s\) smaller than 8 pt .*'0\.0' 6\.0 pt"):
        plotting.savefig(small, "too_small")
    assert not list((output_dir / "figures").glob("*too_small*"))  # (nor a temporary file: pathlib's * matches ".")
    monkeypatch.delenv("WSNLIB_BATCH")
    with pytest.warns(UserWarning, match="smaller than 8 pt"):
        plotting.savefig(small, "too_small")
    # Wide figures are shrunk in the notebook: 10 pt on a 20-inch figure is too small too.
    monkeypatch.setenv("WSNLIB_BATCH", "1")
    with pytest.raises(ValueError, match="too_wide"):
        plotting.savefig(_figure_with_text(20.0, 10.0), "too_wide")
    plotting.savefig(_figure_with_text(7.0, plotting.MIN_FONT_PT), "legible")
    plt.close("all")


def test_the_style_and_every_plot_helper_meet_the_minimum_size(output_dir, monkeypatch):
    """Default sizes from use_style(), heatmap cell numbers, annotations, the Pareto legend."""
    monkeypatch.setenv("WSNLIB_BATCH", "1")
    plotting.use_style()
    fig, axes = plt.subplots(2, 2, figsize=(7.5, 6), layout="constrained")
    t = np.arange(50) / 50.0
    plotting.plot_angle_traces(t, {"truth": t, "hybrid": t}, ax=axes[0, 0], title="traces")
    plotting.plot_heatmap(np.arange(64.0).reshape(8, 8) / 7, list(range(8)), list(range(8)), ax=axes[0, 1],
                          fmt="{:.3g}", title="heatmap")
    plotting.plot_tradeoff([1.0, 2.0], [3.0, 1.0], ["β=0.1", "β=0.2"], ax=axes[1, 0], logy=True)
    plotting.plot_pareto(np.array([1.0, 2.0]), np.array([2.0, 1.0]), front=[True, True], knee=0,
                         references={"data fusion": (3.0, 3.0)}, ax=axes[1, 1])
    fig.suptitle("all helpers")
    sizes = plotting.effective_font_sizes(fig)
    assert min(size for _, size in sizes) >= plotting.MIN_FONT_PT
    assert {"traces", "heatmap", "β=0.1", "recommended (knee)", "all helpers"} <= {text for text, _ in sizes}
    plotting.savefig(fig, "helpers")
    plt.close(fig)


def test_style_cycles_okabe_ito_and_paper_002_methods_have_palette_colours():
    with matplotlib.rc_context():
        plotting.use_style()
        cycle = [c["color"] for c in matplotlib.rcParams["axes.prop_cycle"]]
    assert set(cycle) <= set(plotting.OKABE_ITO.values())
    for name in ("deterministic", "probabilistic", "kinect", "radio only", "hybrid", "none", "gating", "lowpass"):
        assert plotting.METHOD_COLORS[name] in plotting.OKABE_ITO.values()
    # Notebook 05's estimators: every one in the palette, each with a marker; a peer's hybrid
    # variants share its colour, so colour and marker together tell all of them apart.
    from wsnlib.orientation.loss_handling import PAPER_OPTIONS

    peers = ("Fusion", "Fusion + hybrid (output)", "Fusion + hybrid (feedback)",
             "VQF", "VQF + hybrid (output)", "VQF + hybrid (feedback)")
    loss_study = (*PAPER_OPTIONS, "single frame", *peers)
    assert all(plotting.METHOD_COLORS[name] in plotting.OKABE_ITO.values() for name in loss_study)
    assert all(plotting.METHOD_MARKERS.get(name) for name in loss_study)
    pairs = {(plotting.METHOD_COLORS[name], plotting.METHOD_MARKERS[name]) for name in loss_study}
    assert len(pairs) == len(loss_study)
    # Within paper 002's comparison figure, each approach has its own colour and marker.
    compared = ("deterministic", "probabilistic", "kinect", "radio only", "hybrid")
    assert len({plotting.METHOD_COLORS[n] for n in compared}) == len(compared)
    assert len({plotting.METHOD_MARKERS[n] for n in compared}) == len(compared)


def test_method_style_gives_colour_marker_label_and_refuses_unknown_names():
    style = plotting.method_style("kinect", ls=":")
    assert style == {"color": plotting.METHOD_COLORS["kinect"], "marker": "^", "label": "kinect", "ls": ":"}
    with pytest.raises(ValueError, match="METHOD_COLORS"):
        plotting.method_style("no such method")


def test_break_at_gaps_inserts_nan_after_each_jump_only():
    x = np.array([0.0, 0.1, 0.2, 1.0, 1.1, 3.0])
    y = np.arange(6.0)
    xb, yb = plotting.break_at_gaps(x, y)
    np.testing.assert_array_equal(np.isnan(xb), [0, 0, 0, 1, 0, 0, 1, 0])
    np.testing.assert_array_equal(yb[~np.isnan(yb)], y)
    xb, yb = plotting.break_at_gaps(x, y, max_step=5.0)
    np.testing.assert_array_equal(xb, x)
    with pytest.raises(ValueError, match="increasing"):
        plotting.break_at_gaps(x[::-1], y)
    with pytest.raises(ValueError, match="length"):
        plotting.break_at_gaps(x, y[:3])


def test_heatmap_panels_share_one_colour_scale_and_validate():
    fig, axes = plt.subplots(1, 3, figsize=(7.5, 2.5), layout="constrained")
    low = np.arange(6.0).reshape(2, 3)
    high = low + 10.0
    high[0, 0] = np.nan                                   # left blank, not annotated
    colorbar = plotting.plot_heatmap_panels({"low": low, "high": high}, [1, 2], ["a", "b", "c"], axes=axes,
                                            xlabel="col", ylabel="row", fmt="{:.0f}", colorbar_label="cost (s)")
    images = [ax.get_images()[0] for ax in axes[:2]]
    assert [image.get_clim() for image in images] == [(0.0, 15.0), (0.0, 15.0)]   # shared: min and max of both
    assert colorbar.ax.get_ylabel() == "cost (s)"
    assert [ax.get_title() for ax in axes[:2]] == ["low", "high"]
    assert [text.get_text() for text in axes[1].texts] == ["11", "12", "13", "14", "15"]
    assert not axes[2].get_visible()                      # the extra axes is hidden
    with pytest.raises(ValueError, match="shape"):
        plotting.plot_heatmap_panels({"bad": np.zeros((3, 2))}, [1, 2], [1, 2, 3], axes=axes)
    with pytest.raises(ValueError, match="only 1 axes"):
        plotting.plot_heatmap_panels({"a": low, "b": low}, [1, 2], [1, 2, 3], axes=axes[:1])
    with pytest.raises(ValueError, match="no finite value"):
        plotting.plot_heatmap_panels({"a": np.full((2, 3), np.nan)}, [1, 2], [1, 2, 3], axes=axes)
    plt.close(fig)


@pytest.mark.parametrize(("low", "high"), [(40.0, 90.0), (0.02, 0.5), (1.5e4, 6e4), (3.0, 3e5)])
def test_log_axes_are_labelled_with_plain_numbers(low, high):
    """Issue 26: "6×10¹" becomes "60", on major and minor ticks, for every log axis after use_style()."""
    import pandas as pd

    plotting.use_style()
    fig, (ax_a, ax_b) = plt.subplots(1, 2)
    ax_a.plot([1, 2], [low, high])
    ax_a.set_yscale("log")
    pd.Series([low, high]).plot(ax=ax_b, logy=True)      # pandas' own route to a log axis
    fig.canvas.draw()
    for ax in (ax_a, ax_b):
        ticks = [*ax.yaxis.get_major_ticks(), *ax.yaxis.get_minor_ticks()]
        labels = {(tick.get_loc(), tick.label1.get_text()) for tick in ticks if tick.label1.get_text()}
        assert labels, "no tick is labelled"
        for value, text in labels:
            assert text == plotting.plain_number(value), (value, text)
            assert float(text) == pytest.approx(value, rel=1e-3), (value, text)
    plt.close(fig)


def test_plain_number_keeps_three_significant_digits_and_no_exponent():
    assert [plotting.plain_number(v) for v in (60.0, 0.02, 2e5, 1.0, 0.000123456, 12345.0)] == [
        "60", "0.02", "200000", "1", "0.000123", "12300"]


def test_trace_panels_shade_each_panels_own_loss_and_validate(output_dir, monkeypatch):
    monkeypatch.setenv("WSNLIB_BATCH", "1")
    plotting.use_style()
    t = np.arange(100) / 50.0
    received = np.ones((2, 100), bool)
    received[0, 40:46] = False
    received[1, 40:70] = False
    fig = plotting.plot_trace_panels(t, {"short": {"truth": t, "data fusion": t + 1},
                                         "long": {"truth": t, "data fusion": t + 2}},
                                     received, ylabel="pitch (°)", window=t < 1.8, suptitle="two losses")
    axes = fig.axes
    spans = [[patch.get_x() for patch in ax.patches] for ax in axes]
    assert len(axes) == 2 and spans == [[pytest.approx(0.8)], [pytest.approx(0.8)]]
    widths = [ax.patches[0].get_width() for ax in axes]
    assert widths == [pytest.approx(6 / 50.0), pytest.approx(30 / 50.0)]
    assert axes[0].get_xlabel() == "" and axes[1].get_xlabel() == "time (s)"
    plotting.savefig(fig, "trace_panels")     # legible in the batch
    plt.close(fig)
    with pytest.raises(ValueError, match="received"):
        plotting.plot_trace_panels(t, {"one": {"truth": t}}, received, ylabel="x")


def test_option_tradeoffs_draw_one_line_per_option_from_the_lowest_loss_rate():
    import pandas as pd

    plotting.use_style()
    results = pd.DataFrame({"option": ["hold_last"] * 3 + ["hybrid"] * 3, "loss rate": [0.0, 0.1, 0.2] * 2,
                            "err": [1.0, 2.0, 3.0, 1.0, 1.5, 2.0], "step": [0.0, 0.1, 0.2, 0.0, 1.0, 2.0]})
    fig, axes = plt.subplots(1, 1, squeeze=False)
    plotting.plot_option_tradeoffs(results, axes=axes, error_columns=["err"], smoothness_columns={"step": "step (°)"})
    lines = axes[0, 0].get_lines()
    assert [line.get_label() for line in lines] == ["hold_last", "hybrid"]
    assert list(lines[1].get_xdata()) == [1.5, 2.0]          # the lossless row is left out
    assert axes[0, 0].get_yscale() == "log" and [t.get_text() for t in axes[0, 0].texts] == ["20%", "20%"]
    with pytest.raises(ValueError, match="axes must be"):
        plotting.plot_option_tradeoffs(results, axes=axes, error_columns=["err", "err"],
                                       smoothness_columns={"step": "step (°)"})
    plt.close(fig)


def test_slerp_on_the_sphere_follows_the_quaternion_slerp():
    from wsnlib import quaternion

    q_single = quaternion.from_axis_angle([0.0, 0.0, 1.0], 0.0)
    q_fusion = quaternion.from_axis_angle([0.0, 0.0, 1.0], np.radians(60.0))     # 60° about up
    tips = plotting.slerp_tips(q_single, q_fusion, [0.0, 0.25, 0.5, 1.0])
    angles = np.radians([0.0, 15.0, 30.0, 60.0])                                   # constant speed along the arc
    np.testing.assert_allclose(tips, np.stack([np.cos(angles), np.sin(angles), np.zeros(4)], axis=-1), atol=1e-12)
    plotting.use_style()
    fig = plt.figure(figsize=(7.0, 4.0))
    ax_whole, ax_zoom = fig.add_subplot(1, 2, 1, projection="3d"), fig.add_subplot(1, 2, 2, projection="3d")
    plotting.plot_slerp_on_sphere(q_single, q_fusion, [0.0, 0.5, 1.0], ax=ax_whole)
    plotting.plot_slerp_on_sphere(q_single, q_fusion, [0.0, 0.5, 1.0], ax=ax_zoom, zoom=True, mu_marked=(0.2, "μ"))
    path = [line for line in ax_whole.get_lines() if line.get_label() == "SLERP path"][0]
    xs, ys, zs = path.get_data_3d()
    np.testing.assert_allclose(np.hypot(np.hypot(xs, ys), zs), 1.0)               # on the unit sphere
    labels = [text.get_text().strip() for text in ax_zoom.texts]
    assert labels == ["μ = 0", "μ = 0.5", "μ = 1"]
    assert {"single frame (μ = 0)", "data fusion (μ = 1)", "μ"} <= set(ax_zoom.get_legend_handles_labels()[1])
    plt.close(fig)


def _laid_out_figure():
    """A constrained-layout figure with what moves its layout: a colorbar, a log axis, a legend, a suptitle."""
    plotting.use_style()
    fig, (ax_image, ax_log) = plt.subplots(1, 2, figsize=(7.0, 3.0), layout="constrained")
    image = ax_image.imshow(np.arange(12.0).reshape(3, 4))
    fig.colorbar(image, ax=ax_image, label="value (°)")
    ax_log.plot([1.0, 2.0, 3.0], [1.0, 10.0, 100.0], label="a series")
    ax_log.set_yscale("log")
    ax_log.legend()
    fig.suptitle("a suptitle")
    return fig


def _media_box(pdf: bytes) -> np.ndarray:
    import re

    return np.array(re.search(rb"/MediaBox \[ *([-\d. ]+)\]", pdf).group(1).split(), float)


def test_savefig_writes_matplotlibs_own_files_and_leaves_the_figure_as_it_was(output_dir):
    """savefig lays the figure out once for both files; the PNG is the bytes matplotlib's own
    savefig writes (which lays it out anew per file), the PDF has its page size, and the figure
    keeps its layout engine and dpi (a notebook then shows it as before)."""
    import io

    fig = _laid_out_figure()
    engine, dpi = fig.get_layout_engine(), fig.dpi
    png, pdf = plotting.savefig(fig, "laid_out")
    assert fig.get_layout_engine() is engine and fig.dpi == dpi
    own = {}
    for fmt in ("png", "pdf"):
        buffer = io.BytesIO()
        _laid_out_figure().savefig(buffer, format=fmt, metadata=plotting.style._PNG_METADATA if fmt == "png"
                                   else plotting.style._PDF_METADATA)
        own[fmt] = buffer.getvalue()
    assert png.read_bytes() == own["png"]
    np.testing.assert_allclose(_media_box(pdf.read_bytes()), _media_box(own["pdf"]), atol=0.5)  # points
    with matplotlib.rc_context({"savefig.bbox": None}):  # not cropped: the figure's own size
        (whole,) = plotting.savefig(fig, "whole", formats="png")
    dots = matplotlib.rcParams["savefig.dpi"]
    assert plt.imread(whole).shape[:2] == (round(3.0 * dots), round(7.0 * dots))
    plt.close("all")


def test_savefig_restores_the_figure_when_it_refuses(output_dir, monkeypatch):
    monkeypatch.setenv("WSNLIB_BATCH", "1")
    small = _figure_with_text(6.0, 6.0)
    small.set_layout_engine("constrained")
    engine, dpi = small.get_layout_engine(), small.dpi
    with pytest.raises(ValueError, match="smaller than"):
        plotting.savefig(small, "refused")
    assert small.get_layout_engine() is engine and small.dpi == dpi
    plt.close("all")


def test_a_notebook_shows_the_saved_png_instead_of_drawing_the_figure_again(output_dir):
    """Under the inline backend the cell shows the saved file itself, once, at the width the backend's own
    drawing would have had; a figure saved as PDF only, or one pyplot does not manage (shown as the
    cell's value), is drawn by IPython as before, once."""
    import base64

    import nbclient
    import nbformat

    from wsnlib import paths

    cells = ["import matplotlib.pyplot as plt\nfrom matplotlib.figure import Figure\nfrom wsnlib import plotting\n"
             "plotting.use_style()",
             'fig, ax = plt.subplots(figsize=(4, 3))\nax.plot([0, 1])\nplotting.savefig(fig, "shown");',
             'fig, ax = plt.subplots()\nax.plot([1, 0])\nplotting.savefig(fig, "pdf_only", formats="pdf");',
             'static = Figure()\nstatic.add_subplot().plot([0, 1])\nplotting.savefig(static, "unmanaged")\nstatic']
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(source) for source in cells])
    nbclient.NotebookClient(nb, kernel_name=paths.KERNEL_NAME, timeout=120,
                            resources={"metadata": {"path": str(output_dir)}}).execute()
    images = [[output for output in cell.outputs if "image/png" in output.get("data", {})] for cell in nb.cells]
    assert [len(shown) for shown in images] == [0, 1, 1, 1]
    saved = (output_dir / "figures" / "shown.png").read_bytes()
    (shown,) = images[1]
    assert base64.b64decode(shown["data"]["image/png"]) == saved
    saved_width_px = int.from_bytes(saved[16:20], "big")  # the PNG header's IHDR width
    with matplotlib.rc_context():
        plotting.use_style()  # the dpi the notebook's figures have, and that of their saved PNG
        dpi_ratio = matplotlib.rcParams["figure.dpi"] / matplotlib.rcParams["savefig.dpi"]
    assert abs(shown["metadata"]["image/png"]["width"] - saved_width_px * dpi_ratio) <= 1
    unmanaged = (output_dir / "figures" / "unmanaged.png").read_bytes()
    assert base64.b64decode(images[3][0]["data"]["image/png"]) != unmanaged  # drawn again, as the cell's value
