"""The loss-tolerance study's registries: methods with their grids, and the loss profiles.

:func:`default_methods` and :data:`PROFILES` are notebook 10's (issue 11's study),
:func:`paper001_methods` and :func:`paper001_profiles` notebook 05's (paper 001's options on real
recordings).  What each method and profile is, and why the grids are as they are: the package
docstring, :mod:`wsnlib.studies.loss_tolerance`.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
from collections.abc import Callable, Mapping

import numpy as np

from wsnlib.loss import LossProfile, hold_last
from wsnlib.orientation import (
    KalmanSettings,
    SingleFrameGate,
    estimate_orientation,
    fusion_orientation,
    kalman_orientation,
    smooth_orientation,
    triad,
    vqf_orientation,
)
from wsnlib.studies.hybrid_tuning import hybrid_options, mu_options

#: Sampling rate of the study (Hz): the paper's 50 Hz; BROAD is resampled to it.
FS = 50.0
#: Largest grid of any method (the tuning budget, the same for peers and ours).
MAX_SETTINGS = 8
#: Madgwick's recommended β (rad/s), the data-fusion gain inside our hybrid.
MADGWICK_BETA = 0.041
#: Kinds of method: causal (ours), peer (other libraries), offline.
KINDS = ("causal", "peer", "offline")
#: Latency rules: name → what the method waits for before its estimate of a sample is final.
LATENCY_RULES = {"none": "0 s: causal, each sample on arrival",
                 "gap": "up to the gap's length: waits for the first sample after a gap",
                 "offline": "the whole recording (offline)"}


@dataclasses.dataclass(frozen=True)
class Method:
    """One entry of the registry: how to run a method with a setting, its grid, kind and latency.

    Attributes
    ----------
    name : str
    kind : {"causal", "peer", "offline"}
    grid : tuple of dict
        Settings tried by the tuning (at most :data:`MAX_SETTINGS`).
    run : callable
        ``run(recording, setting, received) -> quat``: ``received`` ``(M, T)`` bool, ``quat``
        ``(M, T, 4)`` ENU quaternions, signals of ``recording`` sampled at :data:`FS`.
    latency : {"none", "gap", "offline"}
        Key of :data:`LATENCY_RULES`.
    """

    name: str
    kind: str
    grid: tuple
    run: Callable
    latency: str = "none"

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {self.kind!r}")
        if self.latency not in LATENCY_RULES:
            raise ValueError(f"latency must be one of {tuple(LATENCY_RULES)}, got {self.latency!r}")
        if not 1 <= len(self.grid) <= MAX_SETTINGS:
            raise ValueError(f"grid of {self.name!r} must hold 1 to {MAX_SETTINGS} settings, got {len(self.grid)}")


def _madgwick(rec, setting, received, **options):
    return estimate_orientation(rec.gyr, rec.acc, rec.mag, fs=FS, beta=setting["beta"], received=received,
                                **options)


def _hybrid(rec, setting, received, *, gated=False):
    return estimate_orientation(rec.gyr, rec.acc, rec.mag, fs=FS, beta=MADGWICK_BETA, received=received,
                                blend="feedback", rho=1.0, tau=setting["rho_tau"],
                                single_frame_gate=SingleFrameGate() if gated else None)


def _peer(rec, setting, received, *, library, hybrid, gated=False, gap="hold"):
    signals = [np.broadcast_to(x, received.shape + (3,)) for x in (rec.gyr, rec.acc, rec.mag)]
    extra = {"blend": "feedback", "rho": 1.0, "tau": setting["rho_tau"]} if hybrid else {}
    if gated:
        extra["single_frame_gate"] = SingleFrameGate()
    if library == "Fusion":
        return fusion_orientation(*signals, fs=FS, received=received, gain=setting["gain"], gap=gap, **extra)
    params = {"tauAcc": setting["tauAcc"], "tauMag": setting["tauMag"]}
    return vqf_orientation(*signals, fs=FS, received=received, params=params, gap=gap, **extra)


def _kalman(rec, setting, received, *, offline):
    """The Kalman filter (or the smoother, whose forward pass it is) with ``setting``: ``replay`` as
    a keyword, the other entries :class:`~wsnlib.orientation.KalmanSettings` fields."""
    setting = dict(setting)
    replay = setting.pop("replay", True)
    function = smooth_orientation if offline else kalman_orientation
    return function(rec.gyr, rec.acc, rec.mag, fs=FS, received=received, settings=KalmanSettings(**setting),
                    replay=replay)


def settings_grid(fixed: Mapping | None = None, **axes) -> tuple[dict, ...]:
    """Every combination of the values of ``axes`` (the first axis varies slowest), plus ``fixed``.

    ``settings_grid({"mag_norm_gate": 0.05}, replay=(True, False))`` →
    ``({"mag_norm_gate": 0.05, "replay": True}, {"mag_norm_gate": 0.05, "replay": False})``.
    """
    fixed = dict(fixed or {})
    for name, values in axes.items():
        if isinstance(values, (str, bytes)) or not hasattr(values, "__iter__") or len(values) == 0:
            raise ValueError(f"{name} must be a non-empty sequence of values, got {values!r}")
    return tuple({**fixed, **dict(zip(axes, combination, strict=True))}
                 for combination in itertools.product(*axes.values()))


#: Madgwick's β (rad/s) tried for every Madgwick variant.
BETA_GRID = settings_grid(beta=(0.01, 0.02, 0.041, 0.07, 0.1, 0.2, 0.4, 0.8))
#: ρτ (samples) of our hybrid, ρ = 1 (plain and gated).
HYBRID_GRID = settings_grid(rho_tau=(1, 3, 6, 12, 24, 48, 96, 192))
#: Our Kalman filter and smoother (``replay``, and :class:`wsnlib.orientation.KalmanSettings`
#: fields; the rest at their defaults): gap replay on/off, how strongly the accelerometer's noise
#: grows with the recent linear-acceleration level, and the order / window (s) of the linear
#: prediction of the rate in a gap (paired: a longer window carries a longer model).  One grid
#: for both, since the smoother's forward pass is the filter; each is tuned on its own score.
KALMAN_GRID = tuple({"replay": replay, "acc_disturbance_factor": factor,
                     "gap_rate_prediction_order": order, "gap_rate_prediction_window_s": window}
                    for replay in (True, False) for factor in (4.0, 16.0) for order, window in ((24, 3.0), (48, 6.0)))
#: Fusion's gain (plain and with constant-rate prediction in a gap).
FUSION_GRID = settings_grid(gain=(0.1, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0))
#: Fusion wrapped in our hybrid (plain and gated): gain × ρτ (samples).
FUSION_HYBRID_GRID = settings_grid(gain=(0.5, 2.0), rho_tau=(6, 24, 96, 384))
#: VQF's τ_acc, τ_mag (s): the first 8 of a 3 × 3 product (plain and with constant-rate prediction).
VQF_GRID = settings_grid(tauAcc=(1.0, 3.0, 10.0), tauMag=(3.0, 9.0, 30.0))[:MAX_SETTINGS]
#: VQF with its authors' defaults, wrapped in our hybrid: ρτ (samples).
VQF_HYBRID_GRID = settings_grid({"tauAcc": 3.0, "tauMag": 9.0}, rho_tau=(6, 24, 96, 384))


def default_methods(grids: Mapping[str, tuple] | None = None) -> dict[str, Method]:
    """The registry: method name → :class:`Method` (a new method is one more entry).

    Names follow notebook 05 (and :data:`wsnlib.plotting.METHOD_COLORS`).  ``"VQF (defaults)"``
    is VQF with its authors' parameters (tuned by them on BROAD), the reference of the lossless
    target.  The *gated* hybrids apply the single frame only where
    :class:`wsnlib.orientation.SingleFrameGate` (its defaults) trusts it; the peers ``", constant
    rate"`` keep turning at the last received rate in a gap (``gap="constant_rate"``, no decay)
    instead of holding their output.

    Parameters
    ----------
    grids : mapping method name → sequence of dict, optional
        Grids replacing the default ones (module constants such as :data:`KALMAN_GRID`) of the
        methods named, e.g. ``{"Kalman": settings_grid(replay=(True, False))}``; each
        holds 1 to :data:`MAX_SETTINGS` settings.
    """
    entries = [
        Method("hold_last", "causal", BETA_GRID, _madgwick),
        Method("constant_rate", "causal", BETA_GRID, functools.partial(_madgwick, gap="constant_rate")),
        Method("gyro_interpolation", "causal", BETA_GRID, functools.partial(_madgwick, replay=True),
               latency="gap"),
        Method("hybrid (feedback)", "causal", HYBRID_GRID, _hybrid),
        Method("gated hybrid (feedback)", "causal", HYBRID_GRID, functools.partial(_hybrid, gated=True)),
        Method("Kalman", "causal", KALMAN_GRID, functools.partial(_kalman, offline=False)),
        Method("smoother", "offline", KALMAN_GRID, functools.partial(_kalman, offline=True), latency="offline"),
        Method("Fusion", "peer", FUSION_GRID, functools.partial(_peer, library="Fusion", hybrid=False)),
        Method("Fusion, constant rate", "peer", FUSION_GRID,
               functools.partial(_peer, library="Fusion", hybrid=False, gap="constant_rate")),
        Method("Fusion + hybrid (feedback)", "peer", FUSION_HYBRID_GRID,
               functools.partial(_peer, library="Fusion", hybrid=True)),
        Method("Fusion + gated hybrid (feedback)", "peer", FUSION_HYBRID_GRID,
               functools.partial(_peer, library="Fusion", hybrid=True, gated=True)),
        Method("VQF", "peer", VQF_GRID, functools.partial(_peer, library="VQF", hybrid=False)),
        Method("VQF, constant rate", "peer", VQF_GRID,
               functools.partial(_peer, library="VQF", hybrid=False, gap="constant_rate")),
        Method("VQF (defaults)", "peer", ({"tauAcc": 3.0, "tauMag": 9.0},),
               functools.partial(_peer, library="VQF", hybrid=False)),
        Method("VQF + hybrid (feedback)", "peer", VQF_HYBRID_GRID,
               functools.partial(_peer, library="VQF", hybrid=True)),
    ]
    methods = {m.name: m for m in entries}
    for name, grid in dict(grids or {}).items():
        if name not in methods:
            raise ValueError(f"grids names an unknown method {name!r}; known: {', '.join(methods)}")
        methods[name] = dataclasses.replace(methods[name], grid=tuple(grid))
    return methods


#: Pairs (without, with) of the study's two side questions: does gating the single frame
#: help the hybrids, and does constant-rate prediction in a gap help the peers?
GATING_PAIRS = (("hybrid (feedback)", "gated hybrid (feedback)"),
                ("Fusion + hybrid (feedback)", "Fusion + gated hybrid (feedback)"))
GAP_PREDICTION_PAIRS = (("Fusion", "Fusion, constant rate"), ("VQF", "VQF, constant rate"))


def quick_methods(methods: Mapping[str, Method] | None = None, n_settings: int = 2) -> dict[str, Method]:
    """The registry with each grid cut to its first ``n_settings`` settings (quick mode)."""
    methods = default_methods() if methods is None else methods
    return {name: dataclasses.replace(m, grid=m.grid[:n_settings]) for name, m in methods.items()}


#: Name of the headline profile (tuning and targets).
HEADLINE = "GE 10 %"

#: The profiles of the study, in order (the first is lossless: the reference of the burst response).
PROFILES = (
    LossProfile.none("lossless"),
    LossProfile.burst(4.0, 4, period_s=8.0, name="paper burst"),
    LossProfile.gilbert_elliott(0.05),
    LossProfile.gilbert_elliott(0.10, name=HEADLINE),
    LossProfile.gilbert_elliott(0.20),
    LossProfile.gilbert_elliott(0.10, samples_per_packet=1, name="GE 10 %, 1-sample packets"),
    LossProfile.gilbert_elliott(0.10, samples_per_packet=12, name="GE 10 %, 12-sample packets"),
)


# ------------------------------------------------------------------------------------------
# Notebook 05: paper 001's options on real recordings, beside the peers
# ------------------------------------------------------------------------------------------


def _paper_option(rec, setting, received, *, options):
    return estimate_orientation(rec.gyr, rec.acc, rec.mag, fs=FS, beta=setting["beta"], received=received,
                                **options)


def _single_frame(rec, setting, received):
    return hold_last(triad(rec.acc, rec.mag), received)


def _peer_with_blend(rec, setting, received, *, library, blend_options):
    signals = [np.broadcast_to(x, received.shape + (3,)) for x in (rec.gyr, rec.acc, rec.mag)]
    if library == "Fusion":
        return fusion_orientation(*signals, fs=FS, received=received, gain=setting["gain"], **blend_options)
    return vqf_orientation(*signals, fs=FS, received=received, params={"tauAcc": setting["tauAcc"]}, **blend_options)


def paper001_methods(hybrid: Mapping, beta_grid, fusion_gain_grid, vqf_tau_acc_grid) -> dict[str, Method]:
    """Notebook 05's registry: paper 001's options, the single frame and the peers, plain and in the hybrid.

    Paper 001's options (:data:`wsnlib.orientation.loss_handling.PAPER_OPTIONS`) on Madgwick's
    filter, each over ``beta_grid`` (rad/s): ``hold_last``, ``dt_extension``,
    ``gyro_interpolation`` (latency rule "gap"), ``adaptive_beta`` (μ of ``hybrid``) and
    ``hybrid`` (``hybrid``'s blend and μ); ``single frame`` (TRIAD held over gaps, nothing to
    tune); Fusion over ``fusion_gain_grid`` and VQF over ``vqf_tau_acc_grid`` (``tauAcc``, s; its
    other parameters its authors'), each plain and wrapped in the hybrid with output and with
    feedback blending (μ of ``hybrid``).  One grid per filter, the same size for each, as the
    notebook's tuning budget.

    Parameters
    ----------
    hybrid : mapping
        The hybrid setting (``schedule``, ``blend``, ``rho``, ``tau``[, ``hold_window``]), e.g.
        :data:`wsnlib.studies.hybrid_tuning.RECOMMENDED_HYBRID`.
    beta_grid, fusion_gain_grid, vqf_tau_acc_grid : sequence of float
    """
    betas, gains, taus = (settings_grid(beta=beta_grid), settings_grid(gain=fusion_gain_grid),
                          settings_grid(tauAcc=vqf_tau_acc_grid))
    options = {"hold_last": {}, "dt_extension": {"method": "dt_extension"}, "gyro_interpolation": {"replay": True},
               "adaptive_beta": {"method": "adaptive_beta", **mu_options(hybrid)}, "hybrid": hybrid_options(hybrid)}
    entries = [Method(name, "causal", betas, functools.partial(_paper_option, options=option),
                      latency="gap" if name == "gyro_interpolation" else "none") for name, option in options.items()]
    entries.append(Method("single frame", "causal", ({},), _single_frame))
    for library, grid in (("Fusion", gains), ("VQF", taus)):
        entries.append(Method(library, "peer", grid, functools.partial(_peer_with_blend, library=library,
                                                                       blend_options={})))
        for blend in ("output", "feedback"):
            entries.append(Method(f"{library} + hybrid ({blend})", "peer", grid,
                                  functools.partial(_peer_with_blend, library=library,
                                                    blend_options={"blend": blend, **mu_options(hybrid)})))
    return {m.name: m for m in entries}


def paper001_profiles(ge_loss_rates=(0.05, 0.10, 0.20), mean_burst_packets: float = 3.0, burst_packets: int = 4,
                      burst_period_s: float = 8.0) -> tuple[LossProfile, ...]:
    """Notebook 05's profiles: lossless, the paper's burst repeated every ``burst_period_s`` from half a
    period on ("paper burst"), and Gilbert–Elliott at each rate (6-sample packets)."""
    return (LossProfile.none("lossless"),
            LossProfile.burst(burst_period_s / 2, burst_packets, period_s=burst_period_s, name="paper burst"),
            *(LossProfile.gilbert_elliott(rate, mean_burst_packets) for rate in ge_loss_rates))
