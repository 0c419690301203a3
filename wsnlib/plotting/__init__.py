"""Plot style, figure saving and the figures of the notebooks, one module per concern.

* :mod:`wsnlib.plotting.style` — the palette (:data:`OKABE_ITO`, :data:`METHOD_COLORS`,
  :data:`METHOD_MARKERS`), :func:`use_style` (with log axes in plain numbers,
  :class:`PlainLogScale`), the legibility limits and :func:`savefig`, the one way figures are
  written (byte-reproducible PNG and PDF).
* :mod:`wsnlib.plotting.traces` — angle and error traces with lost samples shaded (also stacked,
  one panel per loss), bands, trade-offs, the paper's arm figure.
* :mod:`wsnlib.plotting.grids` — annotated heatmaps and Pareto fronts of parameter searches.
* :mod:`wsnlib.plotting.study_results` — panels of one burst loss and of static fingerprinting.
* :mod:`wsnlib.plotting.loss_options` — the loss options' error against smoothness (notebook 04).
* :mod:`wsnlib.plotting.slerp_sphere` — SLERP drawn on the unit sphere (paper 001, Fig. 5; notebook 02).
* :mod:`wsnlib.plotting.loss_tolerance` — figures of the loss-tolerance study (notebook 10).
* :mod:`wsnlib.plotting.testbed` — paper 002's testbed as we assume it (anchor layout, its Fig. 4).
* :mod:`wsnlib.plotting.streaming` — figures of the live receiver (notebook 11) and its live frame.

Every public name is re-exported here, so ``plotting.savefig``, ``plotting.use_style()`` and
``plotting.ANNOTATION_FONT_PT`` work as before the split.  Module-level state (the palette
dictionaries, the style, the font limits) lives only in :mod:`wsnlib.plotting.style`: the
dictionaries re-exported here are the same objects, but to patch a constant in a test, patch
it there (``monkeypatch.setattr(wsnlib.plotting.style, "MIN_FONT_PT", ...)``).
"""

from wsnlib.plotting.grids import plot_heatmap, plot_heatmap_panels, plot_pareto
from wsnlib.plotting.loss_options import plot_option_tradeoffs
from wsnlib.plotting.loss_tolerance import plot_burst_traces, plot_error_vs_loss_rate, plot_per_trial_dots
from wsnlib.plotting.slerp_sphere import plot_slerp_on_sphere, slerp_tips
from wsnlib.plotting.streaming import (
    LiveFigure,
    plot_body_frame,
    plot_burst_coverage,
    plot_latency_curve,
    plot_live_error,
    plot_redundancy_tradeoff,
)
from wsnlib.plotting.study_results import plot_burst_recovery, plot_hybrid_vs_fusion, plot_static_fingerprinting
from wsnlib.plotting.style import (
    ANNOTATION_FONT_PT,
    DISPLAY_WIDTH_IN,
    METHOD_COLORS,
    METHOD_MARKERS,
    MIN_FONT_PT,
    OKABE_ITO,
    PlainLogScale,
    effective_font_sizes,
    method_style,
    plain_number,
    savefig,
    use_style,
)
from wsnlib.plotting.testbed import plot_anchor_layout
from wsnlib.plotting.traces import (
    break_at_gaps,
    loss_spans,
    plot_angle_traces,
    plot_arm_angles,
    plot_band,
    plot_trace_panels,
    plot_tradeoff,
)

__all__ = ["ANNOTATION_FONT_PT", "DISPLAY_WIDTH_IN", "LiveFigure", "METHOD_COLORS", "METHOD_MARKERS", "MIN_FONT_PT",
           "OKABE_ITO", "PlainLogScale", "break_at_gaps", "effective_font_sizes", "loss_spans", "method_style",
           "plain_number", "plot_anchor_layout", "plot_angle_traces", "plot_arm_angles", "plot_band",
           "plot_body_frame", "plot_burst_coverage", "plot_burst_recovery", "plot_burst_traces",
           "plot_error_vs_loss_rate", "plot_heatmap", "plot_heatmap_panels", "plot_hybrid_vs_fusion",
           "plot_latency_curve", "plot_live_error", "plot_option_tradeoffs", "plot_pareto", "plot_per_trial_dots",
           "plot_redundancy_tradeoff", "plot_slerp_on_sphere", "plot_static_fingerprinting", "plot_trace_panels",
           "plot_tradeoff", "savefig", "slerp_tips", "use_style"]
