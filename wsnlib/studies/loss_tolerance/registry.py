"""The loss-tolerance study's registries: methods with their grids and search spaces, and the loss profiles.

:func:`default_methods` and :data:`PROFILES` are notebook 10's (issue 11's study),
:func:`paper001_methods` and :func:`paper001_profiles` notebook 05's (paper 001's options on real
recordings).  A method to tune is defined by its search space (each setting's physical bounds,
and why, in the ``*_SPACE`` constants); its grid is :func:`space_grid` of it within a budget, the
same for every method (:data:`DEFAULT_BUDGET`; :func:`with_budget` for another).  The ablation
(:data:`ABLATION`: filter × gap handling) and the peers as users run them today
(:data:`AS_USERS_RUN_THEM`) name methods of the registry.  What each method and profile is: the
package docstring, :mod:`wsnlib.studies.loss_tolerance`.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
from collections.abc import Callable, Mapping

import numpy as np

from wsnlib._validation import check_count
from wsnlib.loss import LossProfile, burst_mask, hold_last
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
    """A setting's range in a search space: its physical bounds ``low`` to ``high`` (in ``unit``,
    for the reason ``why``), spaced evenly on a log scale with ``log``, rounded to an integer with
    ``integer`` (floats keep 3 significant digits, so give bounds with at most 3)."""

    low: float
    high: float
    log: bool = True
    integer: bool = False
    unit: str = ""
    why: str = ""

    def __post_init__(self):
        if not (np.isfinite(self.low) and np.isfinite(self.high) and self.low < self.high):
            raise ValueError(f"Range needs finite low < high, got {self.low!r}, {self.high!r}")
        if self.log and self.low <= 0:
            raise ValueError(f"a log Range needs low > 0, got {self.low!r}")
        if self._round(self.low) != self.low or self._round(self.high) != self.high:
            precision = "integers" if self.integer else "3 significant digits"
            raise ValueError(f"Range bounds must keep their value when rounded to {precision}, got {self.low!r}, "
                             f"{self.high!r}")

    def _round(self, x: float):
        return int(round(x)) if self.integer else float(f"{x:.3g}")

    def levels(self, n: int) -> tuple:
        """``n`` values from ``low`` to ``high``, both bounds included, evenly spaced (on a log scale
        with ``log``); ``n = 1``: the middle of the range.  ``ValueError`` when rounding makes two
        values equal (an integer range too narrow for ``n`` values)."""
        n = check_count(n, "n")
        fractions = np.array([0.5]) if n == 1 else np.linspace(0.0, 1.0, n)
        if self.log:
            raw = np.exp(np.log(self.low) + fractions * (np.log(self.high) - np.log(self.low)))
        else:
            raw = self.low + fractions * (self.high - self.low)
        values = tuple(self._round(float(x)) for x in raw)
        if len(set(values)) != n:
            raise ValueError(f"{n} levels of the Range {self.low:g}-{self.high:g} are not distinct after rounding: "
                             f"{values}")
        return values


@dataclasses.dataclass(frozen=True)
class Choice:
    """A setting taking each of ``values`` in a search space (every value in every budget)."""

    values: tuple
    why: str = ""

    def __post_init__(self):
        if len(self.values) == 0:
            raise ValueError("Choice needs at least one value")

    def levels(self, n: int | None = None) -> tuple:
        """Every value (a choice is not thinned by the budget)."""
        return tuple(self.values)


@dataclasses.dataclass(frozen=True)
class Method:
    """One entry of the registry: how to run a method with a setting, its search space and grid,
    kind and latency.

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
        The search space: each setting's physical bounds (:class:`Range`) or values
        (:class:`Choice`).  The registry's grids are :func:`space_grid` of it, and
        :func:`with_budget` makes the grid again for another budget; empty (default): the grid
        is fixed (e.g. a peer at its authors' defaults).
    default : dict, optional
        The setting used without tuning (a study of a single recording, where leave-one-out
        has nothing to tune on): the method's documented default.  None (default): the grid's
        only setting; a method with a longer grid and no default cannot run untuned.
    designs : tuple of dict
        Design alternatives chosen in the fold together with the grid (e.g.
        :data:`KALMAN_DESIGNS`): the grid is every design × every setting of the space
        (:func:`method_grid`), so the design is chosen on the trials of the other groups only.
        Empty (default): the method's design is fixed.
    setting_of : str, optional
        Run with the setting chosen for that method (its grid must be this one's) instead of
        tuning on its own score: the smoother takes its causal filter's, whose forward pass it
        is (one settings object for both).  None (default): tuned on its own score.
    """

    name: str
    kind: str
    grid: tuple
    run: Callable
    latency: str = "none"
    space: Mapping = dataclasses.field(default_factory=dict)
    default: Mapping | None = None
    designs: tuple = ()
    setting_of: str | None = None

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
        for design in self.designs:
            if not isinstance(design, Mapping) or set(design) & set(self.space):
                raise ValueError(f"each design of {self.name!r} must be a dict of settings outside its search space "
                                 f"{sorted(self.space)}, got {design!r}")

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
    _used(setting, ("beta", "rho_tau"), "the hybrid")
    return estimate_orientation(rec.gyr, rec.acc, rec.mag, fs=rec.fs, beta=setting["beta"], received=received,
                                blend="feedback", rho=1.0, tau=setting["rho_tau"],
                                single_frame_gate=SingleFrameGate() if gated else None)


#: Fusion's rejection timeout (s) when a setting switches its rejection on: Fusion's example's 5 s.
FUSION_REJECTION_TIMEOUT_S = 5.0


def _fusion_settings(setting) -> dict | None:
    """``imufusion`` settings of a study setting: ``rejection_deg`` (°) is both the acceleration and
    the magnetic rejection, with :data:`FUSION_REJECTION_TIMEOUT_S`; absent: Fusion's defaults (off)."""
    if "rejection_deg" not in setting:
        return None
    angle = setting["rejection_deg"]
    return {"acceleration_rejection": angle, "magnetic_rejection": angle,
            "rejection_timeout": FUSION_REJECTION_TIMEOUT_S}


def _peer(rec, setting, received, *, library, hybrid=False, gated=False, **options):
    """Fusion (``setting["gain"]`` and, if given, ``rejection_deg``, :func:`_fusion_settings`) or VQF
    (``setting``'s ``tauAcc`` and ``tauMag``, its authors' values where not given).  ``hybrid``:
    wrapped in our hybrid, feedback blend, ρ = 1 and τ = ``setting["rho_tau"]`` (``gated``: behind
    :class:`~wsnlib.orientation.SingleFrameGate`); ``options``: more keywords of the peer's function
    (``gap``, ``replay``, or a fixed blend and μ)."""
    _used(setting, (("gain", "rejection_deg") if library == "Fusion" else ("tauAcc", "tauMag"))
          + (("rho_tau",) if hybrid else ()), library)
    signals = [np.broadcast_to(x, received.shape + (3,)) for x in (rec.gyr, rec.acc, rec.mag)]
    if hybrid:
        options.update(blend="feedback", rho=1.0, tau=setting["rho_tau"])
    if gated:
        options["single_frame_gate"] = SingleFrameGate()
    if library == "Fusion":
        return fusion_orientation(*signals, fs=rec.fs, received=received, gain=setting["gain"],
                                  settings=_fusion_settings(setting), **options)
    params = {key: setting[key] for key in ("tauAcc", "tauMag") if key in setting}
    return vqf_orientation(*signals, fs=rec.fs, received=received, params=params, **options)


def _kalman(rec, setting, received, *, offline, gap="ar", replay=True):
    """The Kalman filter (or the smoother, whose forward pass it is) with ``setting``'s
    :class:`~wsnlib.orientation.KalmanSettings` fields and the gap handling ``gap``, ``replay``
    (``"constant_rate"``: constant, as the peers', no decay)."""
    _used(setting, [field.name for field in dataclasses.fields(KalmanSettings)],
          "the smoother" if offline else "the Kalman filter")
    options = {"gap_time_constant": np.inf} if gap == "constant_rate" else {}
    function = smooth_orientation if offline else kalman_orientation
    return function(rec.gyr, rec.acc, rec.mag, fs=rec.fs, received=received, settings=KalmanSettings(**setting),
                    gap=gap, replay=replay, **options)


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


def _axis_counts(space: Mapping, budget: int) -> dict[str, int]:
    """How many levels each axis of ``space`` gets within ``budget`` settings: a :class:`Choice` all its
    values; the :class:`Range` axes as many each as possible (the fewest any gets is the largest
    that fits), then the largest product that fits, then the most equal counts (earlier axes first
    to get the larger ones) — exactly ``budget`` when it factors so (12 = 12 = 4 × 3 = 3 × 2 × 2;
    16 over three ranges: 4 × 2 × 2; 13 over two: 4 × 3)."""
    counts = {key: len(axis.values) for key, axis in space.items() if isinstance(axis, Choice)}
    fixed = int(np.prod(list(counts.values()))) if counts else 1
    if fixed > budget:
        raise ValueError(f"a budget of {budget} settings cannot hold every value of the choices {sorted(counts)} "
                         f"({fixed} combinations)")
    ranges = [key for key, axis in space.items() if isinstance(axis, Range)]

    def splits(room: int, k: int, largest: int):
        """Non-increasing k-tuples of counts ≥ 1, each at most ``largest``, with product ≤ ``room``."""
        if k == 0:
            yield ()
            return
        for first in range(min(room, largest), 0, -1):
            for rest in splits(room // first, k - 1, first):
                yield (first, *rest)

    best = max(splits(budget // fixed, len(ranges), budget // fixed),
               key=lambda split: (min(split, default=1), int(np.prod(split)), -max(split, default=1)))
    levels = dict(zip(ranges, best, strict=True))
    return {key: counts.get(key, levels.get(key)) for key in space}


def space_grid(space: Mapping, budget: int) -> tuple[dict, ...]:
    """The settings tried for a search space within a budget: every combination of each axis's levels.

    Each :class:`Range` gets ``n`` values from its lower to its upper physical bound, both
    included, evenly spaced on a log scale (:meth:`Range.levels`); each :class:`Choice` all its
    values.  Every range gets as many values as fit, then the product is the largest that fits
    in ``budget`` (:func:`_axis_counts`): with the default budget of 12, one axis gets 12 values,
    two get 4 × 3, three 3 × 2 × 2.  Since both bounds are in the grid, a chosen value
    at a grid edge is at a physical bound (flagged by :func:`~wsnlib.studies.loss_tolerance.
    summary.edge_picks`, not chased past it).

    Parameters
    ----------
    space : mapping setting name → Range or Choice
        At least one axis.
    budget : int
        Settings at most, ≥ the product of the choices' sizes.

    Returns
    -------
    tuple of dict
        The settings, the first axis varying slowest.
    """
    budget = check_count(budget, "budget")
    if not space:
        raise ValueError("space must hold at least one setting's Range or Choice")
    counts = _axis_counts(space, budget)
    return settings_grid(**{key: axis.levels(counts[key]) for key, axis in space.items()})


def method_grid(space: Mapping, budget: int, designs=()) -> tuple[dict, ...]:
    """A method's grid: :func:`space_grid` of its search space, and with ``designs`` (dicts of
    further settings, :attr:`Method.designs`) every design × every setting of it (the design
    varying slowest): ``len(designs) × budget`` settings."""
    grid = space_grid(space, budget)
    return grid if not designs else tuple({**design, **setting} for design in designs for setting in grid)


#: The default tuning budget: settings per method, the same for the peers and for ours.
DEFAULT_BUDGET = 12

#: Why the bounds of every correction time constant are what they are (VQF's τ, Fusion's 1/gain,
#: the Kalman filter's measurement noise over its gyroscope noise).
TIME_CONSTANT_BOUNDS = ("0.1 s, about one 6-sample packet at 50 Hz: faster, the filter is its single-frame "
                        "measurement; 100 s, longer than BROAD's movement phases: slower, it is its gyroscope alone")
#: Madgwick's β (rad/s), for every Madgwick variant: Madgwick's β = √(3/4) × the gyroscope's error.
BETA_SPACE = {"beta": Range(0.00151, 4.53, unit="rad/s",
                            why="Madgwick's β = √(3/4) × the gyroscope's error: 0.1 °/s, a calibrated MEMS "
                                "gyroscope's bias; 300 °/s, in a gap the whole motion is error")}
#: ρτ (samples) of paper 001's eq. (3) with ρ = 1: μ = ρτ / (λ + ρτ), the filter and the single frame
#: weigh equally after a gap of ρτ samples.
RHO_TAU = Range(1, 1000, integer=True, unit="samples",
                why="1: the single frame weighs half after a one-sample gap; 1000 (20 s at 50 Hz): longer than "
                    "any gap here, the blend never acts")
#: Our hybrid (plain and gated): Madgwick's β × ρτ, as Fusion's and VQF's hybrids tune their gains × ρτ.
HYBRID_SPACE = {**BETA_SPACE, "rho_tau": RHO_TAU}
#: Our Kalman filter and smoother: the noise densities (rad·√s) of the accelerometer's tilt and the
#: magnetometer's heading (:class:`~wsnlib.orientation.KalmanSettings` fields; the rest at their
#: defaults).  Over the gyroscope's noise density (0.002 rad/√s) a density is the steady-state
#: correction time constant (a random walk observed in white noise: τ = r / σ_g), so the bounds are
#: those of the peers' time constants, 0.1 s and 100 s.
KALMAN_SPACE = {key: Range(0.0002, 0.2, unit="rad·√s", why=f"time constant / σ_g: {TIME_CONSTANT_BOUNDS}")
                for key in ("acc_noise_density", "mag_noise_density")}
#: The design of our Kalman filter and smoother, chosen in the fold (issue 25's nested
#: leave-one-group-out): the documented defaults of :class:`~wsnlib.orientation.KalmanSettings` (the
#: first, empty design) and, one at a time, each alternative a data-chosen default was picked
#: against on BROAD's 17 trials (``KalmanSettings``' docstring: "chosen most often by LOTO from
#: …"; ``mag_norm_tau_s`` 20 s, VQF's ``magRefTau``, was the default until the drifting-field
#: heading work, ``mag_hard_iron_tau_s`` 3 s until the drifting field with a magnet).  Crossed
#: with the 12 settings of :data:`KALMAN_SPACE` in the
#: ``", design in fold"`` entries of :func:`default_methods`.
KALMAN_DESIGNS = (
    {},
    {"gyro_noise": 0.01},
    {"gap_rate_noise": 1.0},
    {"gap_rate_relative_noise": 0.5},
    {"mag_norm_gate": 0.05},
    {"velocity_noise_density": 0.0707},
    {"mag_hard_iron_min_bias": float("inf")},
    {"mag_norm_tau_s": 20.0},
    {"acc_disturbance_factor": 0.0},
    {"acc_disturbance_factor": 16.0},
    {"gap_rate_prediction_span_s": 0.48, "gap_rate_prediction_window_s": 3.0},
    {"mag_hard_iron_tau_s": 3.0},
)
#: Methods whose defaults (:class:`~wsnlib.orientation.KalmanSettings`) were chosen on BROAD's 17
#: trials: on those trials their scores are *designed on the scored trials* (they stand beside the
#: headline, as its optimism), and the headline takes the ``", design in fold"`` entries instead
#: (:func:`~wsnlib.studies.loss_tolerance.summary.best_methods` ``exclude=``).  On other
#: recordings they are held out like every method.
DESIGNED_ON_BROAD = ("Kalman", "Kalman, hold", "Kalman, constant rate", "Kalman, AR", "smoother")
#: (design in fold, designed on all trials): the headline entries beside the ones they stand for; the
#: difference is the optimism of choosing the design on the scored trials.
DESIGN_PAIRS = (("Kalman, design in fold", "Kalman"), ("smoother, design in fold", "smoother"))
#: Fusion's gain (its correction time constant is 1/gain s) and its acceleration and magnetic
#: rejection (one angle for both, :data:`FUSION_REJECTION_TIMEOUT_S`), for every Fusion variant.
FUSION_SPACE = {"gain": Range(0.01, 10.0, why=f"1/gain is a time constant: {TIME_CONSTANT_BOUNDS}"),
                "rejection_deg": Range(5.0, 90.0, unit="°",
                                       why="5°: rejects most samples in motion; 90°: never rejects (Fusion's "
                                           "default, off)")}
#: VQF's τ_acc and τ_mag (s), for every VQF variant and its offline peers.
VQF_SPACE = {key: Range(0.1, 100.0, unit="s", why=TIME_CONSTANT_BOUNDS) for key in ("tauAcc", "tauMag")}
#: Fusion and VQF wrapped in our hybrid: as ours, the filter's gain × ρτ (Fusion's gain without
#: rejection, its default; VQF's τ_acc, τ_mag its authors' 9 s).
FUSION_HYBRID_SPACE = {"gain": FUSION_SPACE["gain"], "rho_tau": RHO_TAU}
VQF_HYBRID_SPACE = {"tauAcc": VQF_SPACE["tauAcc"], "rho_tau": RHO_TAU}
#: VQF's authors' τ_acc and τ_mag (s): "VQF (defaults)".
VQF_DEFAULTS = {"tauAcc": 3.0, "tauMag": 9.0}


def default_methods(budget: int = DEFAULT_BUDGET) -> dict[str, Method]:
    """The registry: method name → :class:`Method` (a new method is one more entry).

    Every method with something to tune has a search space (the ``*_SPACE`` constants: each
    setting's physical bounds, and why) and, as its grid, ``budget`` settings of it
    (:func:`space_grid`: log-spaced from bound to bound) — the same budget for the peers and for
    ours.  Names follow notebook 05 (and :data:`wsnlib.plotting.METHOD_COLORS`).

    * Madgwick's filter (β) holding its output in a gap (``hold_last``), turning at the last
      rate (``constant_rate``), replaying the gap with a linear rate (``gyro_interpolation``),
      and, for the ablation, with our gap module's AR prediction (``"Madgwick, AR"``) and its
      replay (``"Madgwick, AR + replay"``);
      our hybrid, plain and *gated* (β × ρτ; the gated one applies the single frame only where
      :class:`wsnlib.orientation.SingleFrameGate` trusts it).
    * Our Kalman filter with our gap module (``"Kalman"``: the rate predicted by an AR model in a
      gap and the gap replayed at its end) and, for the ablation (:data:`ABLATION`), with each
      other gap handling (``", hold"``, ``", constant rate"``, ``", AR"`` without replay); its
      smoother, which runs with the setting chosen for the filter (:attr:`Method.setting_of`: its
      forward pass is the filter).  Tuned: the accelerometer's and magnetometer's noise densities.  Their other
      defaults were chosen on BROAD's 17 trials (:data:`DESIGNED_ON_BROAD`), so the filter and the
      smoother come twice more, as ``"Kalman, design in fold"`` and ``"smoother, design in
      fold"``: the design (one of :data:`KALMAN_DESIGNS`) is chosen with the ``budget`` settings
      in the fold (``budget`` × the designs: more than the peers' budget, the price of choosing
      the design without the scored trials).
    * The peers, Fusion (gain × rejection) and VQF (τ_acc × τ_mag), with each gap handling
      (plain = hold; ``", constant rate"``; ``", AR"``; ``", AR + replay"``: the same gap module
      as ours, :mod:`wsnlib.orientation.gaps`), and wrapped in our hybrid (gain or τ_acc × ρτ;
      Fusion's also gated).
    * The peers as users run them today (:data:`AS_USERS_RUN_THEM`): their authors' defaults,
      holding or turning at the last rate in a gap (nothing to tune).  ``"VQF (defaults)"`` is
      also the reference of the lossless target.
    * The smoother's offline peers: ``"offline VQF"`` (:func:`wsnlib.orientation.
      offline_vqf_orientation`, the gaps filled by linear interpolation) and ``"VQF
      forward-backward"`` (VQF holding in a gap, run forwards and backwards and averaged,
      :func:`wsnlib.orientation.forward_backward_orientation`).

    Every method's :attr:`~Method.default` (its setting without tuning, e.g. on a single
    recording) is its documented default: Madgwick's β = :data:`MADGWICK_BETA`; our hybrids'
    ρτ = :data:`DEFAULT_RHO_TAU`; :class:`~wsnlib.orientation.KalmanSettings` (); Fusion's gain
    :data:`FUSION_DEFAULT_GAIN` without rejection; VQF's own parameters.

    Parameters
    ----------
    budget : int
        Settings per method with a search space (default :data:`DEFAULT_BUDGET`); e.g. 2 for a
        quick run, 1000 on a cluster.  :func:`with_budget` changes it for a registry.
    """
    budget = check_count(budget, "budget")
    beta, rho_tau = {"beta": MADGWICK_BETA}, {"rho_tau": DEFAULT_RHO_TAU}
    fusion, kalman = {"gain": FUSION_DEFAULT_GAIN}, {}

    def tuned(name, kind, space, run, default, **options):
        grid = method_grid(space, budget, options.get("designs", ()))
        return Method(name, kind, grid, run, space=space, default=default, **options)

    entries = [
        tuned("hold_last", "causal", BETA_SPACE, _madgwick, beta),
        tuned("constant_rate", "causal", BETA_SPACE, functools.partial(_madgwick, gap="constant_rate"), beta),
        tuned("gyro_interpolation", "causal", BETA_SPACE, functools.partial(_madgwick, replay=True), beta),
        tuned("Madgwick, AR", "causal", BETA_SPACE, functools.partial(_madgwick, gap="ar"), beta),
        tuned("Madgwick, AR + replay", "causal", BETA_SPACE, functools.partial(_madgwick, gap="ar", replay=True),
              beta),
        tuned("hybrid (feedback)", "causal", HYBRID_SPACE, _hybrid, beta | rho_tau),
        tuned("gated hybrid (feedback)", "causal", HYBRID_SPACE, functools.partial(_hybrid, gated=True),
              beta | rho_tau),
        tuned("Kalman", "causal", KALMAN_SPACE, functools.partial(_kalman, offline=False), kalman),
        tuned("Kalman, hold", "causal", KALMAN_SPACE,
              functools.partial(_kalman, offline=False, gap="hold", replay=False), kalman),
        tuned("Kalman, constant rate", "causal", KALMAN_SPACE,
              functools.partial(_kalman, offline=False, gap="constant_rate", replay=False), kalman),
        tuned("Kalman, AR", "causal", KALMAN_SPACE, functools.partial(_kalman, offline=False, replay=False), kalman),
        tuned("smoother", "offline", KALMAN_SPACE, functools.partial(_kalman, offline=True), kalman,
              latency="offline", setting_of="Kalman"),
        tuned("Kalman, design in fold", "causal", KALMAN_SPACE, functools.partial(_kalman, offline=False), kalman,
              designs=KALMAN_DESIGNS),
        tuned("smoother, design in fold", "offline", KALMAN_SPACE, functools.partial(_kalman, offline=True), kalman,
              latency="offline", designs=KALMAN_DESIGNS, setting_of="Kalman, design in fold"),
    ]
    for library, space, hybrid_space, default in (("Fusion", FUSION_SPACE, FUSION_HYBRID_SPACE, fusion),
                                                  ("VQF", VQF_SPACE, VQF_HYBRID_SPACE, {})):
        run = functools.partial(_peer, library=library)
        entries += [
            tuned(library, "peer", space, run, default),
            tuned(f"{library}, constant rate", "peer", space, functools.partial(run, gap="constant_rate"), default),
            tuned(f"{library}, AR", "peer", space, functools.partial(run, gap="ar"), default),
            tuned(f"{library}, AR + replay", "peer", space, functools.partial(run, gap="ar", replay=True), default),
            tuned(f"{library} + hybrid (feedback)", "peer", hybrid_space, functools.partial(run, hybrid=True),
                  default | rho_tau),
        ]
        if library == "Fusion":
            entries.append(tuned("Fusion + gated hybrid (feedback)", "peer", hybrid_space,
                                 functools.partial(run, hybrid=True, gated=True), default | rho_tau))
    defaults = {"Fusion": {"gain": FUSION_DEFAULT_GAIN}, "VQF": VQF_DEFAULTS}
    for library, setting in defaults.items():
        run = functools.partial(_peer, library=library)
        entries += [Method(f"{library} (defaults)", "peer", (setting,), run),
                    Method(f"{library} (defaults), constant rate", "peer", (setting,),
                           functools.partial(run, gap="constant_rate"))]
    entries += [tuned("offline VQF", "offline", VQF_SPACE, _offline_vqf, {}, latency="offline"),
                tuned("VQF forward-backward", "offline", VQF_SPACE, _forward_backward_vqf, {}, latency="offline")]
    return {m.name: m for m in entries}


def with_budget(methods: Mapping[str, Method], budget: int) -> dict[str, Method]:
    """The registry with ``budget`` settings per method: the tuning budget, the same for every method.

    Every method with a search space (:attr:`Method.space`) gets :func:`space_grid` of it as its
    grid — one way to define what is tuned: the space, with its physical bounds.  A method
    without a space (e.g. ``"VQF (defaults)"``: its authors' setting) keeps its grid.
    ``with_budget(methods, 2)`` is the quick mode (each range's two bounds);
    ``with_budget(methods, 1000)`` a cluster's sweep.

    Raises
    ------
    ValueError
        ``budget`` not a positive integer.
    """
    budget = check_count(budget, "budget")
    return {name: dataclasses.replace(method, grid=method_grid(method.space, budget, method.designs))
            if method.space else method for name, method in methods.items()}


def inclination_methods() -> dict[str, Method]:
    """Peers without a magnetometer, scored on inclination only (their heading is arbitrary):
    ``"RIANN"`` (:func:`wsnlib.orientation.riann_orientation`, nothing to tune).  Run as a
    second study on the same masks (:func:`~wsnlib.studies.loss_tolerance.evaluate` draws each
    profile's masks from its own generator) and compared on ``rmse_inclination``."""
    return {"RIANN": Method("RIANN", "peer", ({},), _riann)}


#: Gap handlings of the ablation (:data:`ABLATION`), in order: hold the state; turn at the last
#: received rate; hold, then replay the gap with a linear rate (paper 001's gyroscope
#: interpolation); the AR prediction of our gap module; the AR prediction and the replay.
GAP_HANDLINGS = ("hold", "constant rate", "linear replay", "AR", "AR + replay")
#: The ablation, filter × gap handling → method name (:func:`~wsnlib.studies.loss_tolerance.summary.
#: ablation_table`): what the filter contributes (down a column) and what the gap module contributes
#: (along a row).  The Kalman filter and the peers have no linear-replay variant in the registry.
ABLATION = {
    "Madgwick": {"hold": "hold_last", "constant rate": "constant_rate", "linear replay": "gyro_interpolation",
                 "AR": "Madgwick, AR", "AR + replay": "Madgwick, AR + replay"},
    "Kalman": {"hold": "Kalman, hold", "constant rate": "Kalman, constant rate", "AR": "Kalman, AR",
               "AR + replay": "Kalman"},
    "Fusion": {"hold": "Fusion", "constant rate": "Fusion, constant rate", "AR": "Fusion, AR",
               "AR + replay": "Fusion, AR + replay"},
    "VQF": {"hold": "VQF", "constant rate": "VQF, constant rate", "AR": "VQF, AR", "AR + replay": "VQF, AR + replay"},
}
#: The gap handling of each method of the ablation, of the smoother (its forward pass is
#: ``"Kalman"``'s) and of the design-in-fold entries: which peers have "the same gap handling" as a
#: method of ours.
GAP_HANDLING_OF = {name: gap for row in ABLATION.values() for gap, name in row.items()} | dict.fromkeys(
    ("smoother", "Kalman, design in fold", "smoother, design in fold"), "AR + replay")
#: The peers as users run them today: their authors' defaults, not called while no packet arrives
#: (holding) or turning at the last rate.
AS_USERS_RUN_THEM = ("Fusion (defaults)", "Fusion (defaults), constant rate", "VQF (defaults)",
                     "VQF (defaults), constant rate")

#: Pairs (without, with) of the study's two side questions: does gating the single frame help the
#: hybrids, and does each gap handling help each filter over holding (from :data:`ABLATION`)?
GATING_PAIRS = (("hybrid (feedback)", "gated hybrid (feedback)"),
                ("Fusion + hybrid (feedback)", "Fusion + gated hybrid (feedback)"))
GAP_PREDICTION_PAIRS = tuple((row["hold"], row[gap]) for row in ABLATION.values() for gap in GAP_HANDLINGS[1:]
                             if gap in row)


@dataclasses.dataclass(frozen=True)
class BurstPositions:
    """Paper 001's protocol for one burst: each run loses one burst, and the run is repeated with
    the burst at ``positions`` places over the recording's movement.

    Each burst loses ``burst_packets`` whole packets of ``samples_per_packet`` samples
    (:func:`wsnlib.loss.burst_mask`: on the packet grid, at or after its nominal start).  The
    nominal starts are the movement samples at the quantiles (k + ½)/``positions`` of those that
    leave ``before_s`` before the burst and ``window_s`` after it (all samples of that span when
    none moves), so every burst falls in motion, as the paper's did (an arm extension), and no
    burst carries an earlier one's error.  One mask per position: a row of the results each
    (``draw`` = the position's index).  The response is measured against the error just before
    the burst (:func:`wsnlib.metrics.single_burst_response`).

    Attributes
    ----------
    name : str
    burst_packets, samples_per_packet, positions : int
    before_s : float
        The error before the burst is the mean over this long before it (s).
    window_s : float
        Its response is scored over this long after the burst (s).
    """

    name: str = "paper burst"
    burst_packets: int = 4
    samples_per_packet: int = 6
    positions: int = 8
    before_s: float = 0.5
    window_s: float = 4.0
    model = "burst positions"
    loss_rate = 0.0
    mean_burst_packets = float("nan")

    def __post_init__(self):
        for key in ("burst_packets", "samples_per_packet", "positions"):
            check_count(getattr(self, key), key)
        for key in ("before_s", "window_s"):
            if not (np.isfinite(getattr(self, key)) and getattr(self, key) > 0):
                raise ValueError(f"{key} must be a positive number of seconds, got {getattr(self, key)!r}")

    def starts(self, movement, fs: float) -> np.ndarray:
        """Nominal start samples of the bursts ``(positions,)`` on a recording with this ``movement``
        mask ``(T,)`` at ``fs`` (Hz); ``ValueError`` when the recording is too short for one."""
        movement = np.asarray(movement, dtype=bool)
        n = movement.size
        before, after = int(np.ceil(self.before_s * fs)), int(np.ceil(self.window_s * fs))
        lost = (self.burst_packets + 1) * self.samples_per_packet  # the burst, and its shift onto the packet grid
        last = n - lost - after
        if last < before:
            raise ValueError(f"a recording of {n} samples at {fs:g} Hz is too short for a burst with "
                             f"{self.before_s:g} s before and {self.window_s:g} s after it")
        span = np.arange(before, last + 1)
        moving = span[movement[span]]
        candidates = moving if moving.size else span
        quantiles = (np.arange(self.positions) + 0.5) / self.positions
        return candidates[np.floor(quantiles * candidates.size).astype(int)]

    def masks(self, movement, fs: float) -> np.ndarray:
        """Received masks ``(positions, T)``, one burst each (at :meth:`starts`)."""
        n = np.asarray(movement).size
        return np.stack([burst_mask(n, int(start), self.burst_packets, self.samples_per_packet)
                         for start in self.starts(movement, fs)])


#: Name of the headline profile (tuning and targets).
HEADLINE = "GE 10 %"

def study_profiles(burst_positions: int = 8) -> tuple:
    """The profiles of the study, in order (the first is lossless: the reference of the gap response):
    lossless; the paper's burst, one per run at ``burst_positions`` places (:class:`BurstPositions`);
    Gilbert–Elliott 5, 10 (:data:`HEADLINE`) and 20 % (mean burst 3 packets of 6 samples); and
    GE 10 % with 1- and 12-sample packets."""
    return (
        LossProfile.none("lossless"),
        BurstPositions(positions=burst_positions),
        LossProfile.gilbert_elliott(0.05),
        LossProfile.gilbert_elliott(0.10, name=HEADLINE),
        LossProfile.gilbert_elliott(0.20),
        LossProfile.gilbert_elliott(0.10, samples_per_packet=1, name="GE 10 %, 1-sample packets"),
        LossProfile.gilbert_elliott(0.10, samples_per_packet=12, name="GE 10 %, 12-sample packets"),
    )


#: The profiles of the study with 8 burst positions (:func:`study_profiles`).
PROFILES = study_profiles()


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
