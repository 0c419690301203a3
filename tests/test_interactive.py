"""wsnlib.interactive: static small multiples in the batch, a widget panel live, checked knobs."""

import ipywidgets
import numpy as np
import pytest
from matplotlib.figure import Figure

from wsnlib import interactive, paths


class Recorder:
    """A draw function that records its calls and draws one line."""

    def __init__(self, title=None):
        self.calls = []
        self.axes = []
        self.title = title

    def __call__(self, ax, **values):
        self.calls.append(values)
        self.axes.append(ax)
        ax.plot([0, 1], [0, len(self.calls)], label="line")
        ax.legend()
        if self.title:
            ax.set_title(self.title)


@pytest.fixture
def batch(monkeypatch):
    monkeypatch.setenv(paths.BATCH_ENV_VAR, "1")


@pytest.fixture
def live(monkeypatch):
    monkeypatch.delenv(paths.BATCH_ENV_VAR, raising=False)


def test_in_batch_reads_the_environment(monkeypatch):
    for value in ("1", "true", "yes", "on", "TRUE", " Yes "):  # issue 23: "true"/"yes" were read as false
        monkeypatch.setenv("WSNLIB_BATCH", value)
        assert paths.in_batch()
    for value in ("0", "", "false", "no", "off", "No"):
        monkeypatch.setenv("WSNLIB_BATCH", value)
        assert not paths.in_batch()
    monkeypatch.setenv("WSNLIB_BATCH", "ja")
    with pytest.raises(ValueError, match=r"\$WSNLIB_BATCH must be one of .*got 'ja'"):
        paths.in_batch()
    monkeypatch.delenv("WSNLIB_BATCH")
    assert not paths.in_batch()


def test_batch_draws_one_axes_per_static_setting(batch):
    draw = Recorder()
    static = [{"a": 1, "b": "x"}, {"a": 3, "b": "y"}, {"a": 2}]
    fig = interactive.explore(draw, {"a": [1, 2, 3], "b": ["x", "y"]}, static=static, ncols=2)
    assert isinstance(fig, Figure)
    assert len(fig.axes) == 3
    # Left-out knobs take their starting value: the middle of a slider, the first of a drop-down.
    assert draw.calls == [{"a": 1, "b": "x"}, {"a": 3, "b": "y"}, {"a": 2, "b": "x"}]
    assert draw.axes == fig.axes
    assert [ax.get_title() for ax in fig.axes] == ["a=1, b=x", "a=3, b=y", "a=2, b=x"]
    # Only the first panel keeps its legend.
    assert [ax.get_legend() is not None for ax in fig.axes] == [True, False, False]


def test_batch_default_settings_take_a_few_values_along_each_knob(batch):
    draw = Recorder()
    fig = interactive.explore(draw, {"a": [1, 2, 3, 4, 5], "b": ["x", "y"]})
    assert draw.calls == [{"a": 1, "b": "x"}, {"a": 3, "b": "x"}, {"a": 5, "b": "x"}, {"a": 3, "b": "y"}]
    assert len(fig.axes) == 4


def test_batch_keeps_a_title_set_by_draw(batch):
    fig = interactive.explore(Recorder(title="mine"), {"a": [1, 2]}, static=[{"a": 1}, {"a": 2}])
    assert [ax.get_title() for ax in fig.axes] == ["mine", "mine"]


def test_dict_and_widget_knobs(batch):
    draw = Recorder()
    choice = ipywidgets.SelectMultiple(options=["A1", "A2", "A3"], value=["A1", "A3"])
    fig = interactive.explore(draw, {"subset": {"all": (0, 1, 2), "two": (0, 1)}, "anchors": choice},
                              static=[{"subset": (0, 1)}, {"anchors": ("A2",)}])
    assert draw.calls == [{"subset": (0, 1), "anchors": ("A1", "A3")}, {"subset": (0, 1, 2), "anchors": ("A2",)}]
    assert fig.axes[0].get_title() == "subset=two, anchors=A1,A3"
    # Default settings: a widget contributes its value.
    draw = Recorder()
    interactive.explore(draw, {"anchors": choice})
    assert draw.calls == [{"anchors": ("A1", "A3")}]


def test_live_returns_an_undisplayed_widget_that_redraws(live, monkeypatch):
    import IPython.display

    shown = []
    monkeypatch.setattr(IPython.display, "display", lambda *objs, **kw: shown.extend(objs))
    draw = Recorder()
    choice = ipywidgets.SelectMultiple(options=["A1", "A2"], value=["A1"])
    panel = interactive.explore(draw, {"a": [0.1, 0.2, 0.5], "mode": ["x", "y"], "anchors": choice})
    assert isinstance(panel, ipywidgets.interactive)
    assert panel not in shown
    slider, dropdown, multiple = panel.children[:3]
    assert isinstance(slider, ipywidgets.SelectionSlider) and slider.value == 0.2
    assert isinstance(dropdown, ipywidgets.Dropdown) and dropdown.value == "x"
    assert multiple is choice
    assert draw.calls == [{"a": 0.2, "mode": "x", "anchors": ("A1",)}]
    slider.value = 0.5
    assert draw.calls[-1] == {"a": 0.5, "mode": "x", "anchors": ("A1",)}
    assert all(isinstance(obj, Figure) for obj in shown) and len(shown) == 2


def test_live_shows_the_message_of_a_setting_the_study_refuses(live, monkeypatch):
    """A ValueError of compute (e.g. no anchor chosen) becomes a note on the panel, not a traceback."""
    import IPython.display

    shown = []
    monkeypatch.setattr(IPython.display, "display", lambda *objs, **kw: shown.extend(objs))

    def compute(anchors):
        if not anchors:
            raise ValueError("anchors must name at least one anchor")
        return np.arange(len(anchors), dtype=float)

    def draw(result, *, ax):
        ax.plot(result, label="line")

    choice = ipywidgets.SelectMultiple(options=["A1", "A2"], value=["A1"])
    interactive.explore(draw, {"anchors": choice}, compute=compute)
    assert shown[-1].axes[0].get_lines() and not shown[-1].axes[0].texts
    choice.value = ()
    ax = shown[-1].axes[0]
    assert not ax.get_lines() and "at least one anchor" in ax.texts[0].get_text()


@pytest.mark.parametrize("knobs", [
    {},
    [("a", [1, 2])],
    {"not an identifier": [1, 2]},
    {"a": []},
    {"a": {}},
    {"a": "abc"},
    {"a": 3},
    {"a": np.zeros((2, 2))},
    {"a": [1, 2, 1]},
    {"a": ipywidgets.Button()},
], ids=["empty", "not-a-dict", "bad-name", "no-values", "empty-dict", "string", "scalar", "2-d", "duplicate",
        "not-a-value-widget"])
@pytest.mark.parametrize("mode", ["batch", "live"])
def test_bad_knobs_raise_value_error(knobs, mode, monkeypatch):
    monkeypatch.setenv(paths.BATCH_ENV_VAR, "1" if mode == "batch" else "0")
    draw = Recorder()
    with pytest.raises(ValueError):
        interactive.explore(draw, knobs)
    assert draw.calls == []


@pytest.mark.parametrize("static", [[], [{"c": 1}], [{"a": 4}], [("a", 1)], {"a": 1}])
def test_bad_static_raises_value_error(batch, static):
    with pytest.raises(ValueError):
        interactive.explore(Recorder(), {"a": [1, 2, 3]}, static=static)


def test_bad_draw_and_ncols(batch):
    with pytest.raises(TypeError):
        interactive.explore("draw", {"a": [1, 2]})
    with pytest.raises(ValueError, match="ncols"):
        interactive.explore(Recorder(), {"a": [1, 2]}, ncols=0)


def test_start_sets_the_starting_values(batch):
    draw = Recorder()
    interactive.explore(draw, {"a": [1, 2, 3], "b": ["x", "y"]}, start={"a": 1, "b": "y"}, static=[{}, {"a": 3}])
    assert draw.calls == [{"a": 1, "b": "y"}, {"a": 3, "b": "y"}]
    for start in ({"c": 1}, {"a": 4}, [("a", 1)], {"w": ("A1",)}):
        with pytest.raises(ValueError):
            interactive.explore(Recorder(), {"a": [1, 2, 3], "w": ipywidgets.SelectMultiple(options=["A1"])},
                                start=start)


def test_compute_then_draw_per_panel(batch):
    """With compute, each panel draws compute(**values) with draw(result, ax=ax)."""
    computed, drawn = [], []

    def compute(a, b):
        computed.append({"a": a, "b": b})
        return np.array([a, 10 * a])

    def draw(result, *, ax):
        drawn.append((result, ax))
        ax.plot([0, 1], result, label="line")

    fig = interactive.explore(draw, {"a": [1, 2, 3], "b": ["x", "y"]}, compute=compute,
                              static=[{"a": 1}, {"a": 3, "b": "y"}])
    assert computed == [{"a": 1, "b": "x"}, {"a": 3, "b": "y"}]
    assert [ax for _, ax in drawn] == fig.axes
    np.testing.assert_array_equal(drawn[1][0], [3, 30])
    np.testing.assert_array_equal(fig.axes[1].get_lines()[0].get_ydata(), [3, 30])
    assert fig.axes[1].get_title() == "a=3, b=y"
    with pytest.raises(TypeError, match="compute"):
        interactive.explore(draw, {"a": [1, 2]}, compute="not callable")
