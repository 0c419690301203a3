"""The loss-tolerance study's registries: methods with their grids and search spaces, and the loss profiles.

:func:`default_methods` and :data:`PROFILES` are notebook 10's (issue 11's study),
:func:`paper001_methods` and :func:`paper001_profiles` notebook 05's (paper 001's options on real
recordings).  :func:`with_budget` gives every method of a registry the same number of settings
(its hand-picked grid first, then quasi-random draws over its search space).  What each method
and profile is, and why the grids are as they are: the package docstring,
:mod:`wsnlib.studies.loss_tolerance`.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import zlib
from collections.abc import Callable, Mapping

import numpy as np
from scipy.stats import qmc

from wsnlib._validation import check_count
from wsnlib.loss import LossProfile, hold_last
from wsnlib.orientation import (
    KalmanSettings,
    SingleFrameGate,
    estimate_orientation,
    forward_backward_orientation,
    fusion_orientation,
    kalman_orientation,
    offline_vqf_orientation,
    riann_orientation,
    smooth_orientation,
    triad,
    vqf_orientation,
)
from wsnlib.studies.hybrid_tuning import RECOMMENDED_HYBRID, hybrid_options, mu_options

#: The default tuning budget: every hand-picked grid holds at most this many settings (the same
#: for peers and ours); :func:`with_budget` sets another.
DEFAULT_BUDGET = 8
#: Madgwick's recommended β (rad/s), the data-fusion gain inside our hybrid.
MADGWICK_BETA = 0.041
#: ρτ (samples) of our hybrid without tuning: notebook 03's recommended ρ × τ (eq. (3) depends on
#: their product only), so ρ = 1, τ = ρτ is the recommended weight μ(λ).
DEFAULT_RHO_TAU = int(RECOMMENDED_HYBRID["rho"] * RECOMMENDED_HYBRID["tau"])
#: Fusion's gain without tuning: its library's default.
FUSION_DEFAULT_GAIN = 0.5
#: Kinds of method: causal (ours), peer (other libraries), offline.
KINDS = ("causal", "peer", "offline")
#: Latency rules: name → what the method waits for before its estimate of a sample is final.
LATENCY_RULES = {"none": "0 s: causal, each sample final on arrival",
                 "offline": "the whole recording (offline)"}


@dataclasses.dataclass(frozen=True)
class Range:
    """A setting's range in a search space: ``low`` to ``high``, uniform on a log scale with
    ``log``, rounded to an integer with ``integer`` (floats keep 3 significant digits)."""

    low: float
    high: float
    log: bool = True
    integer: bool = False

    def __post_init__(self):
        if not (np.isfinite(self.low) and np.isfinite(self.high) and self.low < self.high):
            raise ValueError(f"Range needs finite low < high, got {self.low!r}, {self.high!r}")
        if self.log and self.low <= 0:
            raise ValueError(f"a log Range needs low > 0, got {self.low!r}")

    def value(self, u: float):
        """The value at ``u`` ∈ [0, 1) of the range."""
        if self.log:
            x = float(np.exp(np.log(self.low) + u * (np.log(self.high) - np.log(self.low))))
        else:
            x = self.low + u * (self.high - self.low)
        return int(round(x)) if self.integer else float(f"{x:.3g}")


@dataclasses.dataclass(frozen=True)
class Choice:
    """A setting taking one of ``values`` (equally often) in a search space."""

    values: tuple

    def __post_init__(self):
        if len(self.values) == 0:
            raise ValueError("Choice needs at least one value")

    def value(self, u: float):
        """The value at ``u`` ∈ [0, 1): ``values[floor(u · len(values))]``."""
        return self.values[min(int(u * len(self.values)), len(self.values) - 1)]


@dataclasses.dataclass(frozen=True)
class Method:
    """One entry of the registry: how to run a method with a setting, its grid, kind, latency
    and search space.

    Attributes
    ----------
    name : str
    kind : {"causal", "peer", "offline"}
    grid : tuple of dict
        Settings tried by the tuning, in order (at least one).
    run : callable
        ``run(recording, setting, received) -> quat``: ``received`` ``(M, T)`` bool, ``quat``
        ``(M, T, 4)`` ENU quaternions; ``recording`` has ``gyr``, ``acc``, ``mag`` ``(T, 3)``
        sampled at its own ``recording.fs`` (Hz), which the method runs at.
        A module-level function or a ``functools.partial`` of one: it is pickled to the
        worker processes of the sweeps.
    latency : {"none", "offline"}
        Key of :data:`LATENCY_RULES`.
    space : mapping setting name → Range or Choice
        Where :func:`with_budget` draws settings beyond ``grid``; empty (default): nothing to
        tune beyond the grid.
    default : dict, optional
        The setting used without tuning (a study of a single recording, where leave-one-out
        has nothing to tune on): the method's documented default.  None (default): the grid's
        only setting; a method with a longer grid and no default cannot run untuned.
    """

    name: str
    kind: str
    grid: tuple
    run: Callable
    latency: str = "none"
    space: Mapping = dataclasses.field(default_factory=dict)
    default: Mapping | None = None

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"kind must be one of {KINDS}, got {self.kind!r}")
        if self.latency not in LATENCY_RULES:
            raise ValueError(f"latency must be one of {tuple(LATENCY_RULES)}, got {self.latency!r}")
        if len(self.grid) == 0:
            raise ValueError(f"grid of {self.name!r} must hold at least one setting")
        for key, dimension in dict(self.space).items():
            if not isinstance(dimension, Range | Choice):
                raise ValueError(f"space[{key!r}] of {self.name!r} must be a Range or a Choice, got {dimension!r}")
        if self.default is not None and not isinstance(self.default, Mapping):
            raise ValueError(f"default of {self.name!r} must be a setting (dict) or None, got {self.default!r}")

    def untuned_setting(self) -> dict:
        """The setting used without tuning: :attr:`default`, else the grid's only setting.

        Raises ``ValueError`` when there is no default and the grid holds several settings.
        """
        if self.default is not None:
            return dict(self.default)
        if len(self.grid) == 1:
            return dict(self.grid[0])
        raise ValueError(f"method {self.name!r} has {len(self.grid)} settings and no default: it cannot run "
                         f"untuned (give Method(default=...))")


def _used(setting, allowed, method: str) -> None:
    """``ValueError`` if ``setting`` has a key the method does not use (it would be ignored silently)."""
    unused = sorted(set(setting) - set(allowed))
    if unused:
        raise ValueError(f"{method}: setting(s) {unused} are not used by this method; it takes {sorted(allowed)}")


def _madgwick(rec, setting, received, **options):
    _used(setting, ("beta",), "Madgwick")
    return estimate_orientation(rec.gyr, rec.acc, rec.mag, fs=rec.fs, beta=setting["beta"], received=received,
                                **options)


def _hybrid(rec, setting, received, *, gated=False):
    _used(setting, ("rho_tau",), "the hybrid")
    return estimate_orientation(rec.gyr, rec.acc, rec.mag, fs=rec.fs, beta=MADGWICK_BETA, received=received,
                                blend="feedback", rho=1.0, tau=setting["rho_tau"],
                                single_frame_gate=SingleFrameGate() if gated else None)


def _peer(rec, setting, received, *, library, hybrid=False, gated=False, **options):
    """Fusion (``setting["gain"]``) or VQF (``setting``'s ``tauAcc`` and, if given, ``tauMag``; its
    authors' values otherwise).  ``hybrid``: wrapped in our hybrid, feedback blend, ρ = 1 and
    τ = ``setting["rho_tau"]`` (``gated``: behind :class:`~wsnlib.orientation.SingleFrameGate`);
    ``options``: more keywords of the peer's function (``gap``, or a fixed blend and μ)."""
    _used(setting, (("gain",) if library == "Fusion" else ("tauAcc", "tauMag")) + (("rho_tau",) if hybrid else ()),
          library)
    signals = [np.broadcast_to(x, received.shape + (3,)) for x in (rec.gyr, rec.acc, rec.mag)]
    if hybrid:
        options.update(blend="feedback", rho=1.0, tau=setting["rho_tau"])
    if gated:
        options["single_frame_gate"] = SingleFrameGate()
    if library == "Fusion":
        return fusion_orientation(*signals, fs=rec.fs, received=received, gain=setting["gain"], **options)
    params = {key: setting[key] for key in ("tauAcc", "tauMag") if key in setting}
    return vqf_orientation(*signals, fs=rec.fs, received=received, params=params, **options)


def _kalman(rec, setting, received, *, offline):
    """The Kalman filter (or the smoother, whose forward pass it is) with ``setting``: ``replay`` as
    a keyword, the other entries :class:`~wsnlib.orientation.KalmanSettings` fields."""
    _used(setting, ("replay", *(field.name for field in dataclasses.fields(KalmanSettings))),
          "the smoother" if offline else "the Kalman filter")
    setting = dict(setting)
    replay = setting.pop("replay", True)
    function = smooth_orientation if offline else kalman_orientation
    return function(rec.gyr, rec.acc, rec.mag, fs=rec.fs, received=received, settings=KalmanSettings(**setting),
                    replay=replay)


def _offline_vqf(rec, setting, received):
    """VQF's offline variant on the gap-filled recording (``setting``: ``tauAcc``, ``tauMag``)."""
    _used(setting, ("tauAcc", "tauMag"), "offline VQF")
    signals = [np.broadcast_to(x, received.shape + (3,)) for x in (rec.gyr, rec.acc, rec.mag)]
    return offline_vqf_orientation(*signals, fs=rec.fs, received=received, params=dict(setting))


def _forward_backward_vqf(rec, setting, received):
    """VQF (holding in a gap) run forwards and on the time-reversed recording, averaged."""
    _used(setting, ("tauAcc", "tauMag"), "VQF forward-backward")
    signals = [np.broadcast_to(x, received.shape + (3,)) for x in (rec.gyr, rec.acc, rec.mag)]
    return forward_backward_orientation(vqf_orientation, *signals, fs=rec.fs, received=received,
                                        params=dict(setting))


def _riann(rec, setting, received):
    _used(setting, (), "RIANN")
    return riann_orientation(np.broadcast_to(rec.gyr, received.shape + (3,)),
                             np.broadcast_to(rec.acc, received.shape + (3,)), fs=rec.fs, received=received)


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
BETA_SPACE = {"beta": Range(0.005, 1.0)}
#: ρτ (samples) of our hybrid, ρ = 1 (plain and gated).
HYBRID_GRID = settings_grid(rho_tau=(1, 3, 6, 12, 24, 48, 96, 192))
HYBRID_SPACE = {"rho_tau": Range(1, 384, integer=True)}
#: Our Kalman filter and smoother (``replay``, and :class:`wsnlib.orientation.KalmanSettings`
#: fields; the rest at their defaults): gap replay on/off, how strongly the accelerometer's noise
#: grows with the recent linear-acceleration level, and the span / window (s) of the linear
#: prediction of the rate in a gap (paired: a longer window carries a longer model).  One grid
#: for both, since the smoother's forward pass is the filter; each is tuned on its own score.
KALMAN_GRID = tuple({"replay": replay, "acc_disturbance_factor": factor,
                     "gap_rate_prediction_span_s": span, "gap_rate_prediction_window_s": window}
                    for replay in (True, False) for factor in (4.0, 16.0)
                    for span, window in ((0.48, 3.0), (0.96, 6.0)))
#: Beyond the grid (:func:`with_budget`), the span and the window vary independently; a window
#: shorter than 3 × the span makes the filter predict at a constant rate instead.
KALMAN_SPACE = {"replay": Choice((True, False)), "acc_disturbance_factor": Range(1.0, 64.0),
                "gap_rate_prediction_span_s": Range(0.08, 1.28),
                "gap_rate_prediction_window_s": Range(1.0, 10.0)}
#: Fusion's gain (plain and with constant-rate prediction in a gap).
FUSION_GRID = settings_grid(gain=(0.1, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0))
FUSION_SPACE = {"gain": Range(0.05, 32.0)}
#: Fusion wrapped in our hybrid (plain and gated): gain × ρτ (samples).
FUSION_HYBRID_GRID = settings_grid(gain=(0.5, 2.0), rho_tau=(6, 24, 96, 384))
FUSION_HYBRID_SPACE = {"gain": Range(0.25, 8.0), "rho_tau": Range(3, 768, integer=True)}
#: VQF's τ_acc, τ_mag (s): the first 8 of a 3 × 3 product (plain and with constant-rate prediction).
VQF_GRID = settings_grid(tauAcc=(1.0, 3.0, 10.0), tauMag=(3.0, 9.0, 30.0))[:DEFAULT_BUDGET]
VQF_SPACE = {"tauAcc": Range(0.3, 30.0), "tauMag": Range(1.0, 100.0)}
#: VQF with its authors' defaults, wrapped in our hybrid: ρτ (samples).
VQF_HYBRID_GRID = settings_grid({"tauAcc": 3.0, "tauMag": 9.0}, rho_tau=(6, 24, 96, 384))
VQF_HYBRID_SPACE = {"rho_tau": Range(3, 768, integer=True)}


def default_methods(grids: Mapping[str, tuple] | None = None) -> dict[str, Method]:
    """The registry: method name → :class:`Method` (a new method is one more entry).

    Names follow notebook 05 (and :data:`wsnlib.plotting.METHOD_COLORS`).  ``"VQF (defaults)"``
    is VQF with its authors' parameters (tuned by them on BROAD), the reference of the lossless
    target.  Every method's :attr:`~Method.default` (its setting without tuning, e.g. on a single
    recording) is its documented default: Madgwick's β = :data:`MADGWICK_BETA`; our hybrids'
    ρτ = :data:`DEFAULT_RHO_TAU`; the Kalman filter's and smoother's
    :class:`~wsnlib.orientation.KalmanSettings` () with gap replay; Fusion's gain
    :data:`FUSION_DEFAULT_GAIN`; VQF's own parameters (its authors').  The *gated* hybrids apply
    the single frame only where :class:`wsnlib.orientation.SingleFrameGate` (its defaults) trusts
    it; the peers ``", constant rate"`` keep turning at the last received rate in a gap
    (``gap="constant_rate"``, no decay) instead of holding their output, and the peers ``", AR +
    replay"`` get the Kalman filter's own gap handling (:mod:`wsnlib.orientation.gaps`: the rate
    predicted by the AR model in a gap, the gap replayed at its end), the same information as
    ours.  The smoother's offline
    peers: ``"offline VQF"`` (:func:`wsnlib.orientation.offline_vqf_orientation`, the gaps filled
    by linear interpolation) and ``"VQF forward-backward"`` (VQF holding in a gap, run forwards
    and backwards and averaged, :func:`wsnlib.orientation.forward_backward_orientation`), over
    VQF's grid.

    Parameters
    ----------
    grids : mapping method name → sequence of dict, optional
        Grids replacing the default ones (module constants such as :data:`KALMAN_GRID`) of the
        methods named, e.g. ``{"Kalman": settings_grid(replay=(True, False))}``.  For the same
        number of settings for every method, see :func:`with_budget`.
    """
    beta, rho_tau, gain = {"beta": MADGWICK_BETA}, {"rho_tau": DEFAULT_RHO_TAU}, {"gain": FUSION_DEFAULT_GAIN}
    entries = [
        Method("hold_last", "causal", BETA_GRID, _madgwick, space=BETA_SPACE, default=beta),
        Method("constant_rate", "causal", BETA_GRID, functools.partial(_madgwick, gap="constant_rate"),
               space=BETA_SPACE, default=beta),
        Method("gyro_interpolation", "causal", BETA_GRID, functools.partial(_madgwick, replay=True),
               space=BETA_SPACE, default=beta),
        Method("hybrid (feedback)", "causal", HYBRID_GRID, _hybrid, space=HYBRID_SPACE, default=rho_tau),
        Method("gated hybrid (feedback)", "causal", HYBRID_GRID, functools.partial(_hybrid, gated=True),
               space=HYBRID_SPACE, default=rho_tau),
        Method("Kalman", "causal", KALMAN_GRID, functools.partial(_kalman, offline=False), space=KALMAN_SPACE,
               default={}),
        Method("smoother", "offline", KALMAN_GRID, functools.partial(_kalman, offline=True), latency="offline",
               space=KALMAN_SPACE, default={}),
        Method("Fusion", "peer", FUSION_GRID, functools.partial(_peer, library="Fusion"), space=FUSION_SPACE,
               default=gain),
        Method("Fusion, constant rate", "peer", FUSION_GRID,
               functools.partial(_peer, library="Fusion", gap="constant_rate"), space=FUSION_SPACE, default=gain),
        Method("Fusion + hybrid (feedback)", "peer", FUSION_HYBRID_GRID,
               functools.partial(_peer, library="Fusion", hybrid=True), space=FUSION_HYBRID_SPACE,
               default=gain | rho_tau),
        Method("Fusion + gated hybrid (feedback)", "peer", FUSION_HYBRID_GRID,
               functools.partial(_peer, library="Fusion", hybrid=True, gated=True), space=FUSION_HYBRID_SPACE,
               default=gain | rho_tau),
        Method("VQF", "peer", VQF_GRID, functools.partial(_peer, library="VQF"), space=VQF_SPACE, default={}),
        Method("VQF, constant rate", "peer", VQF_GRID,
               functools.partial(_peer, library="VQF", gap="constant_rate"), space=VQF_SPACE, default={}),
        Method("Fusion, AR + replay", "peer", FUSION_GRID,
               functools.partial(_peer, library="Fusion", gap="ar", replay=True), space=FUSION_SPACE, default=gain),
        Method("VQF, AR + replay", "peer", VQF_GRID, functools.partial(_peer, library="VQF", gap="ar", replay=True),
               space=VQF_SPACE, default={}),
        Method("VQF (defaults)", "peer", ({"tauAcc": 3.0, "tauMag": 9.0},), functools.partial(_peer, library="VQF")),
        Method("VQF + hybrid (feedback)", "peer", VQF_HYBRID_GRID,
               functools.partial(_peer, library="VQF", hybrid=True), space=VQF_HYBRID_SPACE, default=rho_tau),
        Method("offline VQF", "offline", VQF_GRID, _offline_vqf, latency="offline", space=VQF_SPACE, default={}),
        Method("VQF forward-backward", "offline", VQF_GRID, _forward_backward_vqf, latency="offline",
               space=VQF_SPACE, default={}),
    ]
    methods = {m.name: m for m in entries}
    for name, grid in dict(grids or {}).items():
        if name not in methods:
            raise ValueError(f"grids names an unknown method {name!r}; known: {', '.join(methods)}")
        methods[name] = dataclasses.replace(methods[name], grid=tuple(grid))
    return methods


def _space_draws(method: Method, n: int, seed: int) -> list[dict]:
    """``n`` settings of ``method``'s space: a scrambled Sobol sequence, the first grid setting's
    other entries kept.  Seeded by ``seed`` and the space and grid (not the name), so methods that
    share both (a pair of :data:`GATING_PAIRS`, the Kalman filter and its smoother) share draws."""
    names = list(method.space)
    key = zlib.crc32(repr((sorted((k, repr(v)) for k, v in method.space.items()), method.grid)).encode())
    sobol = qmc.Sobol(len(names), scramble=True, rng=np.random.default_rng([seed, key]))
    points = sobol.random_base2(int(np.ceil(np.log2(n))))[:n]
    return [{**method.grid[0], **{name: method.space[name].value(u) for name, u in zip(names, point, strict=True)}}
            for point in points]


def with_budget(methods: Mapping[str, Method], budget: int, *, rng: np.random.Generator | None = None
                ) -> dict[str, Method]:
    """The registry with ``budget`` settings per method: the tuning budget, the same for every method.

    A method keeps the first ``budget`` settings of its hand-picked grid; when its grid is
    shorter, quasi-random draws over its search space (:attr:`Method.space`, a scrambled Sobol
    sequence, so the draws cover the space evenly) fill it up.  A method without a space (e.g.
    ``"VQF (defaults)"``: its authors' setting) keeps its grid.  ``with_budget(methods, 2)`` is
    the quick mode; ``with_budget(methods, 1000, rng=...)`` a cluster's sweep.

    Parameters
    ----------
    methods : mapping name → Method
    budget : int
        Settings per method, ≥ 1.
    rng : numpy.random.Generator, optional
        Seeds the draws; needed only when some grid is shorter than ``budget``.

    Raises
    ------
    ValueError
        ``budget`` not a positive integer, or draws needed without ``rng``.
    """
    budget = check_count(budget, "budget")
    short = [name for name, m in methods.items() if m.space and len(m.grid) < budget]
    if short and not isinstance(rng, np.random.Generator):
        raise ValueError(f"a budget of {budget} draws settings for {', '.join(short)}: pass rng, a "
                         f"numpy.random.Generator")
    seed = int(rng.integers(2**63)) if short else 0
    out = {}
    for name, method in methods.items():
        grid = method.grid[:budget]
        if name in short:
            grid = grid + tuple(_space_draws(method, budget - len(grid), seed))
        out[name] = dataclasses.replace(method, grid=grid)
    return out


def inclination_methods() -> dict[str, Method]:
    """Peers without a magnetometer, scored on inclination only (their heading is arbitrary):
    ``"RIANN"`` (:func:`wsnlib.orientation.riann_orientation`, nothing to tune).  Run as a
    second study on the same masks (:func:`~wsnlib.studies.loss_tolerance.evaluate` draws each
    profile's masks from its own generator) and compared on ``rmse_inclination``."""
    return {"RIANN": Method("RIANN", "peer", ({},), _riann)}


#: Pairs (without, with) of the study's two side questions: does gating the single frame
#: help the hybrids, and does constant-rate prediction in a gap help the peers?
GATING_PAIRS = (("hybrid (feedback)", "gated hybrid (feedback)"),
                ("Fusion + hybrid (feedback)", "Fusion + gated hybrid (feedback)"))
GAP_PREDICTION_PAIRS = (("Fusion", "Fusion, constant rate"), ("VQF", "VQF, constant rate"),
                        ("Fusion", "Fusion, AR + replay"), ("VQF", "VQF, AR + replay"))


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


def _single_frame(rec, setting, received):
    return hold_last(triad(rec.acc, rec.mag), received)


def paper001_methods(hybrid: Mapping, beta_grid, fusion_gain_grid, vqf_tau_acc_grid) -> dict[str, Method]:
    """Notebook 05's registry: paper 001's options, the single frame and the peers, plain and in the hybrid.

    Paper 001's options (:data:`wsnlib.orientation.loss_handling.PAPER_OPTIONS`) on Madgwick's
    filter, each over ``beta_grid`` (rad/s): ``hold_last``, ``dt_extension``,
    ``gyro_interpolation``, ``adaptive_beta`` (μ of ``hybrid``) and
    ``hybrid`` (``hybrid``'s blend and μ); ``single frame`` (TRIAD held over gaps, nothing to
    tune); Fusion over ``fusion_gain_grid`` and VQF over ``vqf_tau_acc_grid`` (``tauAcc``, s; its
    other parameters its authors'), each plain and wrapped in the hybrid with output and with
    feedback blending (μ of ``hybrid``).  One grid per filter, the same size for each, as the
    notebook's tuning budget.  Defaults without tuning (:attr:`Method.default`): β =
    :data:`MADGWICK_BETA`, Fusion's gain :data:`FUSION_DEFAULT_GAIN`, VQF's own parameters.

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
    entries = [Method(name, "causal", betas, functools.partial(_madgwick, **option), default={"beta": MADGWICK_BETA})
               for name, option in options.items()]
    entries.append(Method("single frame", "causal", ({},), _single_frame))
    for library, grid, default in (("Fusion", gains, {"gain": FUSION_DEFAULT_GAIN}), ("VQF", taus, {})):
        entries.append(Method(library, "peer", grid, functools.partial(_peer, library=library), default=default))
        for blend in ("output", "feedback"):
            entries.append(Method(f"{library} + hybrid ({blend})", "peer", grid,
                                  functools.partial(_peer, library=library, blend=blend, **mu_options(hybrid)),
                                  default=default))
    return {m.name: m for m in entries}


def paper001_profiles(ge_loss_rates=(0.05, 0.10, 0.20), mean_burst_packets: float = 3.0, burst_packets: int = 4,
                      burst_period_s: float = 8.0) -> tuple[LossProfile, ...]:
    """Notebook 05's profiles: lossless, the paper's burst repeated every ``burst_period_s`` from half a
    period on ("paper burst"), and Gilbert–Elliott at each rate (6-sample packets)."""
    return (LossProfile.none("lossless"),
            LossProfile.burst(burst_period_s / 2, burst_packets, period_s=burst_period_s, name="paper burst"),
            *(LossProfile.gilbert_elliott(rate, mean_burst_packets) for rate in ge_loss_rates))
