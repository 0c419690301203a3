"""Input checks shared by every public function: clear ``ValueError`` naming the argument."""

from __future__ import annotations

import dataclasses
import math
import numbers

import numpy as np


def as_float_array(value, name: str, last_dim: int | None = None, min_ndim: int = 1) -> np.ndarray:
    """Return ``value`` as a finite float64 array, or raise ``ValueError`` naming ``name``.

    Parameters
    ----------
    value : array_like
    name : str
        Argument name used in error messages.
    last_dim : int, optional
        Required size of the last axis (3 for vectors, 4 for quaternions).
    min_ndim : int
        Minimum number of dimensions.
    """
    arr = real_array(value, name)
    if arr.ndim < min_ndim:
        raise ValueError(f"{name} must have at least {min_ndim} dimension(s), got shape {arr.shape}")
    if last_dim is not None and arr.shape[-1] != last_dim:
        raise ValueError(f"{name} must have shape (..., {last_dim}), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(f"{name} contains NaN or inf (first at index {tuple(int(i) for i in bad)})")
    return arr


def real_array(value, name: str) -> np.ndarray:
    """``value`` as a float64 array (not checked finite), or ``ValueError`` naming ``name``: not numeric, or complex."""
    if np.iscomplexobj(value):  # numpy would drop the imaginary part with only a ComplexWarning
        raise ValueError(f"{name} must be real, got complex values")
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array, got {type(value).__name__}") from exc


def check_nonzero_norm(arr: np.ndarray, name: str, what: str) -> np.ndarray:
    """Return ``‖arr‖`` along the last axis; raise if any vector has zero norm."""
    norm = np.linalg.norm(arr, axis=-1)
    if np.any(norm <= 0.0):
        bad = np.argwhere(norm <= 0.0)[0]
        raise ValueError(f"{name} has a zero-norm vector at index {tuple(int(i) for i in bad)} ({what})")
    return norm


def check_positive(value, name: str) -> float:
    """Return ``value`` as a float, raising ``ValueError`` unless it is finite and > 0."""
    return _check_number(value, name, "positive", zero_ok=False)


def check_nonnegative(value, name: str) -> float:
    """Return ``value`` as a float, raising ``ValueError`` unless it is finite and >= 0."""
    return _check_number(value, name, "non-negative", zero_ok=True)


def _check_number(value, name: str, what: str, zero_ok: bool) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a {what} number, got {value!r}") from exc
    if not math.isfinite(number) or number < 0.0 or (number == 0.0 and not zero_ok):
        raise ValueError(f"{name} must be a {what} finite number, got {value!r}")
    return number


def as_bool_mask(value, name: str, shape: tuple[int, ...]) -> np.ndarray:
    """Return a boolean mask broadcast to ``shape``; reject non-boolean dtypes."""
    arr = np.asarray(value)
    if arr.dtype != np.bool_:
        raise ValueError(f"{name} must be a boolean mask, got dtype {arr.dtype}")
    try:
        return np.broadcast_to(arr, shape)
    except ValueError as exc:
        raise ValueError(f"{name} has shape {arr.shape}, which does not fit {shape}") from exc


def check_rng(rng) -> np.random.Generator:
    """Return ``rng`` unless it is not a :class:`numpy.random.Generator` (``ValueError``): every
    random draw of the library comes from a generator the caller passes in."""
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    return rng


def check_count(value, name: str, minimum: int = 1) -> int:
    """Return ``value`` as an ``int``, raising ``ValueError`` unless it is an integer (not a
    bool) of at least ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        what = {0: "a non-negative integer", 1: "a positive integer"}.get(minimum, f"an integer >= {minimum}")
        raise ValueError(f"{name} must be {what}, got {value!r}")
    return int(value)


def check_type(value, cls: type, name: str):
    """Return ``value``, raising ``ValueError`` naming ``name`` unless it is an instance of ``cls``."""
    if not isinstance(value, cls):
        article = "an" if cls.__name__[0] in "AEIOU" else "a"
        raise ValueError(f"{name} must be {article} {cls.__name__}, got {type(value).__name__}")
    return value


def check_choice(value, name: str, choices: tuple[str, ...]) -> str:
    """Return ``value``, raising ``ValueError`` naming ``name`` and the choices unless it is one of
    the strings ``choices``."""
    if not isinstance(value, str) or value not in choices:
        listed = ", ".join(repr(c) for c in choices)
        raise ValueError(f"{name} must be one of {listed}; got {value!r}")
    return value


def check_flag(value, name: str) -> bool:
    """Return ``value`` as a ``bool``, raising ``ValueError`` unless it is True or False (numpy's too)."""
    if not isinstance(value, bool | np.bool_):
        raise ValueError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def check_fields(obj, *, positive=(), nonnegative=(), fractions=(), flags=()) -> None:
    """Check and normalise, in place, the named fields of a frozen dataclass ``obj``.

    ``positive``: finite numbers > 0, ``nonnegative``: finite numbers >= 0, ``fractions``: numbers
    in [0, 1] (all stored as floats); ``flags``: True or False.  Each error names the field.
    """
    for name in positive:
        object.__setattr__(obj, name, check_positive(getattr(obj, name), name))
    for name in nonnegative:
        object.__setattr__(obj, name, check_nonnegative(getattr(obj, name), name))
    for name in fractions:
        value = check_nonnegative(getattr(obj, name), name)
        if value > 1.0:
            raise ValueError(f"{name} must lie in [0, 1], got {value!r}")
        object.__setattr__(obj, name, value)
    for name in flags:
        object.__setattr__(obj, name, check_flag(getattr(obj, name), name))


def check_settings_fields(settings, *, may_be_zero=(), may_be_infinite=None, largest: float = 1e100) -> None:
    """Check and normalise, in place, every field of a frozen settings dataclass: a number > 0.

    ``may_be_zero``: fields that may be 0 (a feature off); ``may_be_infinite``: fields that may
    be ``inf`` (None: every field); finite values above ``largest`` are refused (they would
    overflow when squared).  Each error names ``Class.field``.
    """
    for f in dataclasses.fields(settings):
        name, value = f"{type(settings).__name__}.{f.name}", getattr(settings, f.name)
        try:
            number = float(value)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{name} must be a number, got {value!r}") from exc
        if not (number == 0.0 and f.name in may_be_zero):
            if math.isnan(number) or number <= 0.0:
                raise ValueError(f"{name} must be > 0, got {value!r}")
            if math.isinf(number) and may_be_infinite is not None and f.name not in may_be_infinite:
                raise ValueError(f"{name} must be finite, got {value!r}")
            if largest < number < math.inf:
                raise ValueError(f"{name} = {value!r} is too large (> {largest:g})")
        object.__setattr__(settings, f.name, number)
