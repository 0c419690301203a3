"""Settings objects per method of :func:`wsnlib.orientation.estimate_orientation`: how it dispatches.

A settings object holds exactly the parameters of one method (as ``vqf.VQFParams`` or a
scikit-learn estimator's constructor) and is passed as ``method``::

    from wsnlib.orientation import HybridSettings, estimate_orientation

    hybrid = HybridSettings(beta=0.041, rho=1.0, tau=48.0, blend="feedback")
    quat = estimate_orientation(gyr, acc, mag, fs=50.0, received=mask, method=hybrid)

:func:`~wsnlib.orientation.estimate_orientation` runs on such an object only: its method
keywords (``method="hybrid", beta=0.041, rho=1.0, …``, :data:`METHOD_KEYWORDS`) are a
compatibility layer, turned into the object in one place, :func:`settings_from_arguments`,
so the call above is the same as ``estimate_orientation(gyr, acc, mag, fs=50.0,
received=mask, method="hybrid", beta=0.041, rho=1.0, tau=48.0, blend="feedback")``.  A
keyword a method does not use is ignored there, as it always was (``rho`` with
``method="hold_last"``).  With a settings object, every method keyword must be left out: one
passed beside it is a ``ValueError`` whatever its value, even the keyword's default (the
keywords default to :data:`UNSET`, so "passed" can be told from "left out").  To change a
setting, ``dataclasses.replace(settings, rho=2.0)`` gives a modified copy.

The Kalman filter's settings object is :class:`KalmanMethodSettings` (its noise levels and
gates, a :class:`~wsnlib.orientation.KalmanSettings`, plus the gap options of
``estimate_orientation``); a bare :class:`~wsnlib.orientation.KalmanSettings` passed as
``method`` stands for ``KalmanMethodSettings(settings=that)``.

The objects are frozen dataclasses; values are checked by
:func:`~wsnlib.orientation.estimate_orientation` when it runs (arrays are allowed where the
keyword allows them, e.g. a ``rho`` grid).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar

from wsnlib.orientation import _batch as B
from wsnlib.orientation.kalman import KalmanSettings


class _Unset:
    """Type of :data:`UNSET`."""

    def __repr__(self) -> str:
        return "UNSET"


#: Default of :func:`~wsnlib.orientation.estimate_orientation`'s method keywords: "not passed".
UNSET = _Unset()

#: Loss-handling methods of :func:`~wsnlib.orientation.estimate_orientation` built on Madgwick's filter.
METHODS = ("hold_last", "dt_extension", "gyro_interpolation", "adaptive_beta", "hybrid")
#: Every ``method`` of :func:`~wsnlib.orientation.estimate_orientation`: :data:`METHODS` and the Kalman filter.
ALL_METHODS = METHODS + ("kalman",)
#: Where the hybrid's SLERP acts.
BLENDS = ("output", "feedback")
#: The keywords of :func:`~wsnlib.orientation.estimate_orientation` that a settings object replaces.
METHOD_KEYWORDS = ("beta", "rho", "tau", "schedule", "hold_window", "blend", "beta_max", "gap",
                   "gap_time_constant", "kalman_settings", "single_frame_gate")


@dataclass(frozen=True, eq=False)
class _MadgwickMethodSettings:
    """Base: Madgwick's gain and the gap option, shared by every Madgwick-family method."""

    #: Value of ``estimate_orientation``'s ``method`` that the object stands for.
    method: ClassVar[str] = ""

    beta: Any = None
    gap: str | None = None
    gap_time_constant: Any = None

    def keywords(self) -> dict:
        """The object's settings as :func:`~wsnlib.orientation.estimate_orientation` keywords."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


@dataclass(frozen=True, eq=False)
class HoldLastSettings(_MadgwickMethodSettings):
    """``method="hold_last"``: plain Madgwick under loss.

    Attributes
    ----------
    beta : float or array_like
        Madgwick's gain β (rad/s), >= 0 (required).
    gap : {"hold", "constant_rate"}, optional
        During a gap (default ``"hold"``).
    gap_time_constant : float, optional
        With ``"constant_rate"``: decay time constant of the extrapolated rate (s).
    """

    method: ClassVar[str] = "hold_last"


@dataclass(frozen=True, eq=False)
class DtExtensionSettings(_MadgwickMethodSettings):
    """``method="dt_extension"`` (attributes ``beta``; ``gap`` must stay ``"hold"``)."""

    method: ClassVar[str] = "dt_extension"


@dataclass(frozen=True, eq=False)
class GyroInterpolationSettings(_MadgwickMethodSettings):
    """``method="gyro_interpolation"`` (attributes ``beta``; ``gap`` must stay ``"hold"``)."""

    method: ClassVar[str] = "gyro_interpolation"


@dataclass(frozen=True, eq=False)
class AdaptiveBetaSettings(_MadgwickMethodSettings):
    """``method="adaptive_beta"``: β grows towards ``beta_max`` after a gap.

    Attributes
    ----------
    beta, gap, gap_time_constant
        As :class:`HoldLastSettings`.
    beta_max : float or array_like, optional
        β after a very long gap (default 10 β).
    rho, tau : float or array_like
        ρ, τ of eq. (3) (defaults 2 and 6).
    schedule : {"decay", "hold", "instant"}
        λ_eff after a gap.
    hold_window : int, optional
        For ``schedule="hold"`` only.
    """

    method: ClassVar[str] = "adaptive_beta"

    beta_max: Any = None
    rho: Any = 2.0
    tau: Any = 6.0
    schedule: str = "decay"
    hold_window: Any = None


@dataclass(frozen=True, eq=False)
class HybridSettings(_MadgwickMethodSettings):
    """``method="hybrid"``: paper 001's SLERP towards TRIAD after a gap, eqs. (3)–(4).

    Attributes
    ----------
    beta, gap, gap_time_constant
        As :class:`HoldLastSettings`.
    rho, tau : float or array_like
        ρ, τ of eq. (3) (defaults 2 and 6).
    schedule : {"decay", "hold", "instant"}
        λ_eff after a gap.
    hold_window : int, optional
        For ``schedule="hold"`` only.
    blend : {"output", "feedback"}
        Where the SLERP acts (default ``"output"``).
    single_frame_gate : SingleFrameGate or bool, optional
        The gated hybrid (:class:`wsnlib.orientation.SingleFrameGate`).
    """

    method: ClassVar[str] = "hybrid"

    rho: Any = 2.0
    tau: Any = 6.0
    schedule: str = "decay"
    hold_window: Any = None
    blend: str = "output"
    single_frame_gate: Any = None


@dataclass(frozen=True, eq=False)
class KalmanMethodSettings:
    """``method="kalman"``: the gap-aware error-state Kalman filter (:func:`wsnlib.orientation.kalman_orientation`).

    Attributes
    ----------
    settings : KalmanSettings, optional
        Its noise levels and gates (default ``KalmanSettings()``, tuned on BROAD).
    gap : {"hold", "constant_rate"}, optional
        During a gap (default ``"constant_rate"``: the filter always predicts inside; ``"hold"``
        holds only the output on lost samples).
    gap_time_constant : float, optional
        With ``"constant_rate"``: replaces ``settings.gap_rate_decay_s`` (s).
    """

    method: ClassVar[str] = "kalman"

    settings: Any = None
    gap: str | None = None
    gap_time_constant: Any = None


#: Every settings class, by the ``method`` string it stands for.
METHOD_SETTINGS = {cls.method: cls for cls in (HoldLastSettings, DtExtensionSettings, GyroInterpolationSettings,
                                                 AdaptiveBetaSettings, HybridSettings, KalmanMethodSettings)}
#: What ``method`` of :func:`~wsnlib.orientation.estimate_orientation` may be besides a name.
SETTINGS_TYPES = (*METHOD_SETTINGS.values(), KalmanSettings)


def settings_from_arguments(method, keywords: dict[str, Any]):
    """The settings object that :func:`~wsnlib.orientation.estimate_orientation` runs: the one place
    where its ``method`` and method keywords become one object.

    Parameters
    ----------
    method : str or settings object
        A name of :data:`ALL_METHODS`, an object of :data:`SETTINGS_TYPES` (returned as it is,
        a bare :class:`~wsnlib.orientation.KalmanSettings` wrapped in
        :class:`KalmanMethodSettings`).
    keywords : dict
        The method keywords (:data:`METHOD_KEYWORDS`) as passed; :data:`UNSET` where left out.

    Returns
    -------
    settings
        An object of one of the classes of :data:`METHOD_SETTINGS`.  For a name: the method's
        class with the keywords it has (the others are ignored, except those refused below),
        fields not passed at their defaults.

    Raises
    ------
    ValueError
        A keyword passed beside a settings object (naming it), ``method`` neither a name of
        :data:`ALL_METHODS` nor a settings object, ``kalman_settings`` with a method other than
        ``"kalman"``, ``single_frame_gate`` (not None/False) with a method other than ``"hybrid"``.
    """
    given = {name: value for name, value in keywords.items() if value is not UNSET}
    unknown = sorted(set(given) - set(METHOD_KEYWORDS))
    if unknown:
        raise ValueError(f"not a method keyword: {', '.join(unknown)}")
    if isinstance(method, SETTINGS_TYPES):
        if given:
            names = ", ".join(sorted(given))
            hint = (" (the gap options of the Kalman filter go into method=KalmanMethodSettings(settings=..., "
                    "gap=..., gap_time_constant=...))" if isinstance(method, KalmanSettings) else "")
            raise ValueError(f"{names} passed as keyword beside method={type(method).__name__}(...): give every "
                             f"setting in the settings object, e.g. dataclasses.replace(settings, ...){hint}")
        return KalmanMethodSettings(settings=method) if isinstance(method, KalmanSettings) else method
    if not isinstance(method, str):
        names = ", ".join(cls.__name__ for cls in SETTINGS_TYPES)
        raise ValueError(f"method must be a name ({', '.join(ALL_METHODS)}) or a settings object ({names}); "
                         f"got {type(method).__name__}")
    method = B.check_choice(method, "method", ALL_METHODS)
    gate = given.get("single_frame_gate")
    if gate is not None and gate is not False and method != "hybrid":
        raise ValueError(f"single_frame_gate is only used with method='hybrid', not method={method!r}")
    if method == "kalman":
        given["settings"] = given.pop("kalman_settings", None)
    elif given.get("kalman_settings") is not None:
        raise ValueError(f"kalman_settings is only used with method='kalman', not method={method!r}")
    cls = METHOD_SETTINGS[method]
    fields = {f.name for f in dataclasses.fields(cls)}
    return cls(**{name: value for name, value in given.items() if name in fields})
