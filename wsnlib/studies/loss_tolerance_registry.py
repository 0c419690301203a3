"""The loss-tolerance study's registry: methods with their grids, and the loss profiles.

What each method and profile is, and why the grids are as they are: :mod:`wsnlib.studies.loss_tolerance`
(which runs them, :func:`wsnlib.studies.loss_tolerance.evaluate`, and re-exports every name here).
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
from collections.abc import Callable, Mapping

import numpy as np

from wsnlib import loss
from wsnlib.orientation import (
    KalmanSettings,
    SingleFrameGate,
    estimate_orientation,
    fusion_ahrs,
    kalman_orientation,
    smooth_orientation,
    vqf_orientation,
)

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


def _madgwick(rec, setting, received, *, option, gap=None):
    return estimate_orientation(rec.gyr, rec.acc, rec.mag, fs=FS, beta=setting["beta"], received=received,
                                method=option, gap=gap)


def _hybrid(rec, setting, received, *, gated=False):
    return estimate_orientation(rec.gyr, rec.acc, rec.mag, fs=FS, beta=MADGWICK_BETA, received=received,
                                method="hybrid", blend="feedback", rho=1.0, tau=setting["rho_tau"],
                                single_frame_gate=SingleFrameGate() if gated else None)


def _peer(rec, setting, received, *, library, hybrid, gated=False, gap="hold"):
    signals = [np.broadcast_to(x, received.shape + (3,)) for x in (rec.gyr, rec.acc, rec.mag)]
    extra = {"hybrid": "feedback", "rho": 1.0, "tau": setting["rho_tau"]} if hybrid else {}
    if gated:
        extra["single_frame_gate"] = SingleFrameGate()
    if library == "Fusion":
        return fusion_ahrs(*signals, fs=FS, received=received, gain=setting["gain"], gap=gap, **extra)
    params = {"tauAcc": setting["tauAcc"], "tauMag": setting["tauMag"]}
    return vqf_orientation(*signals, fs=FS, received=received, params=params, gap=gap, **extra)


def _kalman(rec, setting, received, *, offline):
    function = smooth_orientation if offline else kalman_orientation
    return function(rec.gyr, rec.acc, rec.mag, fs=FS, received=received, settings=KalmanSettings(**setting))


def settings_grid(fixed: Mapping | None = None, **axes) -> tuple[dict, ...]:
    """Every combination of the values of ``axes`` (the first axis varies slowest), plus ``fixed``.

    ``settings_grid({"mag_norm_gate": 0.05}, gap_replay=(True, False))`` →
    ``({"mag_norm_gate": 0.05, "gap_replay": True}, {"mag_norm_gate": 0.05, "gap_replay": False})``.
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
#: Our Kalman filter (:class:`wsnlib.orientation.KalmanSettings` fields; the rest at their
#: defaults): gap replay on/off, how strongly the accelerometer's noise grows with the recent
#: linear-acceleration level, and the order / window (s) of the linear prediction of the rate
#: in a gap (paired: a longer window carries a longer model).
KALMAN_GRID = tuple({"gap_replay": replay, "acc_disturbance_factor": factor,
                     "gap_rate_prediction_order": order, "gap_rate_prediction_window_s": window}
                    for replay in (True, False) for factor in (4.0, 16.0) for order, window in ((24, 3.0), (48, 6.0)))
#: Our smoother: the magnetometer's norm gate fixed at 0.05; the accelerometer's noise growth,
#: its innovation gate (χ², 13.8 ≈ 3 dof at 99.7 %) and the rate prediction's order / window.
SMOOTHER_GRID = tuple({"mag_norm_gate": 0.05, "acc_disturbance_factor": factor, "acc_innovation_gate": gate,
                       "gap_rate_prediction_order": order, "gap_rate_prediction_window_s": window}
                      for factor in (4.0, 16.0) for gate in (13.8, 6.0) for order, window in ((24, 3.0), (48, 6.0)))
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
        methods named, e.g. ``{"Kalman": settings_grid(gap_replay=(True, False))}``; each
        holds 1 to :data:`MAX_SETTINGS` settings.
    """
    entries = [
        Method("hold_last", "causal", BETA_GRID, functools.partial(_madgwick, option="hold_last")),
        Method("constant_rate", "causal", BETA_GRID,
               functools.partial(_madgwick, option="hold_last", gap="constant_rate")),
        Method("gyro_interpolation", "causal", BETA_GRID, functools.partial(_madgwick, option="gyro_interpolation"),
               latency="gap"),
        Method("hybrid (feedback)", "causal", HYBRID_GRID, _hybrid),
        Method("gated hybrid (feedback)", "causal", HYBRID_GRID, functools.partial(_hybrid, gated=True)),
        Method("Kalman", "causal", KALMAN_GRID, functools.partial(_kalman, offline=False)),
        Method("smoother", "offline", SMOOTHER_GRID, functools.partial(_kalman, offline=True), latency="offline"),
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


@dataclasses.dataclass(frozen=True)
class LossProfile:
    """A packet-loss pattern.

    Attributes
    ----------
    name : str
    model : {"none", "burst", "gilbert_elliott"}
    loss_rate : float
        Long-run fraction of lost packets (Gilbert–Elliott).
    mean_burst_packets : float
        Mean number of consecutive lost packets (Gilbert–Elliott).
    samples_per_packet : int
    burst_packets : int
        Packets per burst (``"burst"``).
    burst_start_s, burst_period_s : float
        First nominal burst start and the period of the bursts (s).
    response_window_s : float
        Window after each gap in which the error increase and recovery are measured (s).
    """

    name: str
    model: str
    loss_rate: float = 0.0
    mean_burst_packets: float = 3.0
    samples_per_packet: int = loss.SAMPLES_PER_PACKET
    burst_packets: int = 4
    burst_start_s: float = 4.0
    burst_period_s: float = 8.0
    response_window_s: float = 2.0

    def mask(self, n_samples: int, fs: float, rng: np.random.Generator) -> np.ndarray:
        """Received mask ``(n_samples,)``, True = received (``rng`` is used by Gilbert–Elliott only)."""
        if self.model == "none":
            return np.ones(n_samples, dtype=bool)
        if self.model == "burst":
            start, period = int(round(self.burst_start_s * fs)), int(round(self.burst_period_s * fs))
            return loss.burst_train(n_samples, start, period, self.burst_packets, self.samples_per_packet)[0]
        if self.model == "gilbert_elliott":
            packets = loss.gilbert_elliott(loss.n_packets_for(n_samples, self.samples_per_packet), self.loss_rate,
                                           self.mean_burst_packets, rng=rng)
            return loss.packets_to_samples(packets, self.samples_per_packet, n_samples)
        raise ValueError(f"model must be 'none', 'burst' or 'gilbert_elliott', got {self.model!r}")


#: Name of the headline profile (tuning and targets).
HEADLINE = "GE 10 %"

#: The profiles of the study, in order (the first is lossless: the reference of the burst response).
PROFILES = (
    LossProfile("lossless", "none"),
    LossProfile("paper burst", "burst", response_window_s=4.0),
    LossProfile("GE 5 %", "gilbert_elliott", 0.05),
    LossProfile(HEADLINE, "gilbert_elliott", 0.10),
    LossProfile("GE 20 %", "gilbert_elliott", 0.20),
    LossProfile("GE 10 %, 1-sample packets", "gilbert_elliott", 0.10, samples_per_packet=1),
    LossProfile("GE 10 %, 12-sample packets", "gilbert_elliott", 0.10, samples_per_packet=12),
)
