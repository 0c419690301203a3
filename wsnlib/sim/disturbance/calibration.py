"""Calibration of the disturbance model against BROAD: the recorded table and the grid fit.

The levels of :data:`UNDISTURBED_BROAD` and :data:`DISTURBED_BROAD` were chosen on a small
grid (:func:`calibrate_disturbance`, :func:`triad_calibration_table`) so that TRIAD's error on
simulated trials of :func:`wsnlib.sim.arm.movement_set` matches the median and 90th percentile
that TRIAD reaches on BROAD's undisturbed and disturbed trials (:data:`BROAD_TRIAD_ERROR_DEG`,
recorded from the 17 shared trials by :func:`broad_triad_errors`).  What is measured on BROAD
directly, not fitted, is written as such in the docstrings of the constants.  The model itself
(:class:`~wsnlib.sim.disturbance.model.Disturbance`) is in :mod:`wsnlib.sim.disturbance.model`.

Sources
-------
* D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD—A Benchmark for Robust Inertial
  Orientation Estimation", Data 6(7):72, 2021 (CC BY 4.0): the trial groups and the recordings
  from which the numbers below are measured.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pandas as pd

from wsnlib import frames
from wsnlib import quaternion as Q
from wsnlib.sim.disturbance.model import Disturbance


def _grid_setting(base: Disturbance, point: dict) -> Disturbance:
    """``base`` with the grid point's fields replaced; ``magnetic_scale`` multiplies hard iron and dipole."""
    changes = {key: value for key, value in point.items() if key != "magnetic_scale"}
    setting = dataclasses.replace(base, **changes)
    scale = point.get("magnetic_scale", 1.0)
    return dataclasses.replace(setting, hard_iron_ut=setting.hard_iron_ut * scale,
                               dipole_moment_am2=setting.dipole_moment_am2 * scale)


#: BROAD's trial groups, by the word in the trial name.
BROAD_GROUPS = ("undisturbed", "disturbed")

#: The BROAD trials the recorded statistics below come from (the 17 shared ones).
BROAD_CALIBRATION_TRIALS = (
    "02_undisturbed_slow_rotation_B", "04_undisturbed_slow_rotation_with_breaks_A",
    "05_undisturbed_slow_rotation_with_breaks_B", "07_undisturbed_fast_rotation_B",
    "09_undisturbed_fast_rotation_with_breaks_B", "11_undisturbed_slow_translation_B",
    "14_undisturbed_slow_translation_with_breaks_B", "16_undisturbed_fast_translation_B",
    "25_disturbed_tapping_B", "27_disturbed_phone_vibration_B", "29_disturbed_stationary_magnet_B",
    "30_disturbed_stationary_magnet_C", "31_disturbed_stationary_magnet_D", "33_disturbed_attached_magnet_2cm",
    "34_disturbed_attached_magnet_3cm", "35_disturbed_attached_magnet_4cm", "36_disturbed_attached_magnet_5cm",
)

#: The error kinds of :func:`wsnlib.metrics.broad_errors_deg` (total rotation angle; its part
#: about a horizontal axis; its part about the vertical).
ERROR_KINDS = ("total", "inclination", "heading")

#: TRIAD's errors (°) on BROAD, recorded by :func:`broad_triad_errors` from the 17 shared trials
#: (02, 04, 05, 07, 09, 11, 14, 16 undisturbed; 25, 27, 29–31, 33–36 disturbed), resampled to
#: 50 Hz, pooled over each group's movement samples with a valid optical reference; median
#: and 90th percentile, rounded to 0.01°.  The real-data test recomputes them.
BROAD_TRIAD_ERROR_DEG = {
    "undisturbed": {"total": {"median": 10.32, "p90": 66.10},
                    "inclination": {"median": 5.37, "p90": 31.46},
                    "heading": {"median": 7.13, "p90": 45.64}},
    "disturbed": {"total": {"median": 26.39, "p90": 112.52},
                  "inclination": {"median": 12.09, "p90": 47.12},
                  "heading": {"median": 19.03, "p90": 101.57}},
}

#: What the calibration matches: TRIAD's inclination error depends on the accelerometer alone,
#: so matching it pins the translation level and spread, and the total error then pins the
#: magnetic disturbance.
CALIBRATION_KINDS = ("total", "inclination")

#: RMS of the linear acceleration (m/s², earth frame: ``q_ref ⊗ acc ⊗ q_ref* − [0, 0, g]``)
#: on the same samples: geometric mean over each group's trials and the standard deviation of
#: its log — *measured* on BROAD; the calibration keeps the spreads and fits the levels.
BROAD_LINEAR_ACC_RMS = {
    "undisturbed": {"geometric_mean_m_s2": 2.25, "log_sd": 0.98},
    "disturbed": {"geometric_mean_m_s2": 4.26, "log_sd": 0.61},
}

#: Soft-iron residual assumed in both groups (2 % of the field per matrix entry): the order of
#: what remains after a hand-held ellipsoid calibration (AN4246); not fitted.
SOFT_IRON_STD = 0.02

#: The passing object of the disturbed group before calibration: 1 A·m² — a strong permanent
#: magnet or a large steel object — passing 0.1–0.5 m from the arm at walking pace, 1 m/s
#: (*assumed*); the calibration scales it together with the hard iron.
DISTURBED_DIPOLE_MOMENT_AM2 = 1.0

#: Starting points of the calibration (scale 1 of ``magnetic_scale``): *assumed* magnetic levels
#: — undisturbed: a 2 µT uncalibrated hard-iron residual (a few % of the 46 µT field, what a
#: quick calibration leaves); disturbed: a 10 µT offset (BROAD's magnet attached at 2–5 cm
#: shifts the field norm by up to 20 µT, p10 of ‖mag‖ 23 µT at 2 cm against 44 µT) and the
#: passing dipole above — and the translation spreads *measured* on BROAD.
CALIBRATION_BASE = {
    "undisturbed": Disturbance(translation_acc_rms_m_s2=BROAD_LINEAR_ACC_RMS["undisturbed"]["geometric_mean_m_s2"],
                               translation_acc_log_sd=BROAD_LINEAR_ACC_RMS["undisturbed"]["log_sd"],
                               hard_iron_ut=2.0, hard_iron_log_sd=0.5, soft_iron_std=SOFT_IRON_STD),
    "disturbed": Disturbance(translation_acc_rms_m_s2=BROAD_LINEAR_ACC_RMS["disturbed"]["geometric_mean_m_s2"],
                             translation_acc_log_sd=BROAD_LINEAR_ACC_RMS["disturbed"]["log_sd"],
                             hard_iron_ut=10.0, hard_iron_log_sd=1.0, soft_iron_std=SOFT_IRON_STD,
                             dipole_moment_am2=DISTURBED_DIPOLE_MOMENT_AM2),
}

#: The final (second, finer) calibration grids, around the best point of a coarse first pass
#: (translation 1–3.5 m/s², spread 0.6–2, magnetic scale 0.5–4).  ``calibrate_disturbance(group,
#: CALIBRATION_GRIDS[group], base=CALIBRATION_BASE[group])`` (seed 0, 32 repetitions, scored on
#: :data:`CALIBRATION_KINDS`) puts the calibrated settings below first.
CALIBRATION_GRIDS = {
    "undisturbed": {"translation_acc_rms_m_s2": [1.4, 1.5, 1.6], "translation_acc_log_sd": [1.4, 1.5, 1.6, 1.7],
                    "magnetic_scale": [1.5, 2.0, 3.0]},
    "disturbed": {"translation_acc_rms_m_s2": [2.75, 3.0, 3.25, 3.5], "translation_acc_log_sd": [0.9, 1.0, 1.1],
                  "magnetic_scale": [1.0, 1.25, 1.5]},
}

#: Calibrated settings (the best points of :data:`CALIBRATION_GRIDS`).  Undisturbed: body
#: translation of 1.4 m/s² RMS (geometric mean over trials; BROAD measures 2.25 m/s² on its
#: undisturbed trials, which also include the arm's own rotation-induced acceleration) with a
#: wide spread (log-sd 1.5 against the measured 0.98: one fast-translation trial at 19 m/s²
#: makes BROAD's tail) and a 4 µT hard-iron residual.  Disturbed: 3.25 m/s² (BROAD 4.26), an
#: attached-magnet-like offset of 12.5 µT (median) and a passing 1.25 A·m² dipole.  Scores
#: 0.045 and 0.014 (sum of four squared log ratios: the worst statistic off by about 15 % and
#: 10 %).
UNDISTURBED_BROAD = _grid_setting(CALIBRATION_BASE["undisturbed"], {
    "translation_acc_rms_m_s2": 1.4, "translation_acc_log_sd": 1.5, "magnetic_scale": 2.0})
DISTURBED_BROAD = _grid_setting(CALIBRATION_BASE["disturbed"], {
    "translation_acc_rms_m_s2": 3.25, "translation_acc_log_sd": 1.1, "magnetic_scale": 1.25})

#: Relative tolerance within which the calibrated simulator's median and 90th percentile of
#: TRIAD's total error match :data:`BROAD_TRIAD_ERROR_DEG` on seeds other than the
#: calibration's (checked by the tests; seed-to-seed scatter with 32 repetitions is ~10 %, the
#: fit itself is off by up to ~15 %).  Inclination and heading are shown, not held to it: the
#: simulated inclination tail runs ~25 % above BROAD's and the heading tail ~15 % below.
CALIBRATION_TOLERANCE = 0.25

#: The calibrated settings by BROAD group.
BROAD_CALIBRATED = {"undisturbed": UNDISTURBED_BROAD, "disturbed": DISTURBED_BROAD}


def broad_group(trial_name: str) -> str:
    """``"disturbed"`` or ``"undisturbed"`` from a BROAD trial name (``"25_disturbed_tapping_B"``)."""
    parts = str(trial_name).split("_")
    if len(parts) > 1 and parts[1] in BROAD_GROUPS:
        return parts[1]
    raise ValueError(f"trial_name {trial_name!r} names neither an undisturbed nor a disturbed BROAD trial")


def broad_triad_errors(trials=None, data_dir=None, fs: float = 50.0) -> pd.DataFrame:
    """TRIAD's total error (°) on BROAD trials, one row per movement sample with a valid reference.

    Parameters
    ----------
    trials : list of str, optional
        Trial names; default every trial present (:func:`wsnlib.io.broad.broad_trials`).
    data_dir : path, optional
        BROAD folder (default ``$WSNLIB_BROAD_DIR``).
    fs : float
        Rate (Hz) the trials are resampled to first (the project's 50 Hz).

    Returns
    -------
    pandas.DataFrame
        Columns ``trial``, ``group``, ``total_deg``, ``inclination_deg``, ``heading_deg``
        (:func:`wsnlib.metrics.broad_errors_deg`), ``linear_acc_m_s2`` (norm of the earth-frame
        linear acceleration from the optical reference).
    """
    from wsnlib.io.broad import broad_trials, load_broad
    from wsnlib.io.resample import resample_broad
    from wsnlib.metrics import broad_errors_deg
    from wsnlib.orientation import triad

    names = broad_trials(present_only=True, data_dir=data_dir) if trials is None else list(trials)
    if not names:
        raise ValueError("no BROAD trial to evaluate (trials is empty or no file is present)")
    parts = []
    for name in names:
        rec = resample_broad(load_broad(name, data_dir, download=False), fs)
        keep = rec.movement & rec.reference_valid
        errors = broad_errors_deg(triad(rec.acc, rec.mag), rec.quat_ref)
        linear = Q.rotate(rec.quat_ref[keep], rec.acc[keep]) - frames.gravity_specific_force_enu(
            frames.STANDARD_GRAVITY)
        parts.append(pd.DataFrame({
            "trial": rec.name, "group": broad_group(rec.name),
            "total_deg": errors["total"][keep], "inclination_deg": errors["inclination"][keep],
            "heading_deg": errors["heading"][keep], "linear_acc_m_s2": np.linalg.norm(linear, axis=-1)}))
    return pd.concat(parts, ignore_index=True)


def error_statistics(errors_deg) -> dict[str, float]:
    """Median and 90th percentile (°) of pooled errors: ``{"median": …, "p90": …}``."""
    e = np.asarray(errors_deg, dtype=float).ravel()
    if e.size == 0 or not np.all(np.isfinite(e)):
        raise ValueError("errors_deg must be a non-empty array of finite numbers")
    return {"median": float(np.median(e)), "p90": float(np.quantile(e, 0.9))}


def simulated_triad_errors(disturbance: Disturbance | None, *, rng: np.random.Generator, n_repetitions: int = 16,
                           fs: float = 50.0, duration_s: float = 8.0) -> dict[str, np.ndarray]:
    """TRIAD's errors (°) on simulated trials of :func:`wsnlib.sim.arm.movement_set`.

    Every movement is simulated ``n_repetitions`` times (own noise and disturbance) with the
    datasheet sensor model; the errors are BROAD's (:func:`wsnlib.metrics.broad_errors_deg`)
    between TRIAD and the truth, on every sample of both nodes (the movements' rests
    included: the disturbance acts there too).

    Parameters
    ----------
    disturbance : Disturbance or None
        None simulates the clean sensors.
    rng : numpy.random.Generator
    n_repetitions : int
    fs, duration_s : float
        Sampling rate (Hz) and length (s) of the movements.

    Returns
    -------
    dict[str, numpy.ndarray]
        :data:`ERROR_KINDS` → errors, shape ``(n_movements · n_repetitions · 2 · T,)``.
    """
    from wsnlib.metrics import broad_errors_deg
    from wsnlib.orientation import triad
    from wsnlib.sim.arm import arm_kinematics, movement_set
    from wsnlib.sim.imu import simulate_imu

    errors = {kind: [] for kind in ERROR_KINDS}
    for trajectory in movement_set(fs=fs, duration_s=duration_s).values():
        truth = arm_kinematics(trajectory)
        _, acc, mag = simulate_imu(truth, rng=rng, n_runs=n_repetitions, disturbance=disturbance)
        for kind, value in broad_errors_deg(triad(acc, mag), truth.quat).items():
            errors[kind].append(value.ravel())
    return {kind: np.concatenate(value) for kind, value in errors.items()}


def error_table(errors: dict) -> dict[str, dict[str, float]]:
    """:func:`error_statistics` of each error kind: ``{kind: {"median": …, "p90": …}}``."""
    return {kind: error_statistics(errors[kind]) for kind in ERROR_KINDS}


def calibrate_disturbance(group: str, grid: dict, *, base: Disturbance | None = None, seed: int = 0,
                          n_repetitions: int = 32, target: dict | None = None,
                          kinds: tuple[str, ...] = CALIBRATION_KINDS) -> pd.DataFrame:
    """Grid search of disturbance levels so that TRIAD's simulated error matches BROAD's, for one group.

    Each grid point replaces fields of ``base`` (the key ``"magnetic_scale"`` multiplies its
    hard-iron magnitude and dipole moment instead), simulates :func:`simulated_triad_errors`
    with the same ``seed`` at every point (common random numbers, so the score surface is
    smooth) and scores the sum of ``log(simulated/target)²`` over the median and 90th
    percentile of each of ``kinds``.

    Parameters
    ----------
    group : {"undisturbed", "disturbed"}
    grid : dict[str, sequence]
        Field of :class:`Disturbance` (or ``"magnetic_scale"``) → values; every combination
        is tried.
    base : Disturbance, optional
        Default the group's :data:`CALIBRATION_BASE`.
    seed : int
    n_repetitions : int
        Repetitions of each of the four movements.
    target : dict, optional
        ``{kind: {"median": …, "p90": …}}`` (°); default :data:`BROAD_TRIAD_ERROR_DEG` of the
        group.
    kinds : tuple of str
        Error kinds scored (default :data:`CALIBRATION_KINDS`).

    Returns
    -------
    pandas.DataFrame
        One row per grid point: the grid's columns, ``<kind> median (°)`` and
        ``<kind> p90 (°)`` for every kind, ``score``; sorted by score (best first, ties in
        grid order).
    """
    if group not in BROAD_GROUPS:
        raise ValueError(f"group must be one of {BROAD_GROUPS}, got {group!r}")
    if not kinds or set(kinds) - set(ERROR_KINDS):
        raise ValueError(f"kinds must be a non-empty subset of {ERROR_KINDS}, got {kinds!r}")
    if not isinstance(grid, dict) or not grid:
        raise ValueError("grid must be a non-empty dict of field name -> values")
    fields = {f.name for f in dataclasses.fields(Disturbance)} | {"magnetic_scale"}
    unknown = set(grid) - fields
    if unknown:
        raise ValueError(f"grid names unknown fields {sorted(unknown)}; known: {sorted(fields)}")
    base = CALIBRATION_BASE[group] if base is None else base
    target = BROAD_TRIAD_ERROR_DEG[group] if target is None else target
    keys = list(grid)
    rows = []
    for values in itertools.product(*(list(grid[key]) for key in keys)):
        point = {key: float(value) for key, value in zip(keys, values, strict=True)}
        stats = error_table(simulated_triad_errors(_grid_setting(base, point), rng=np.random.default_rng(seed),
                                                   n_repetitions=n_repetitions))
        score = sum(np.log(stats[kind][stat] / target[kind][stat]) ** 2 for kind in kinds for stat in ("median", "p90"))
        row = dict(point)
        for kind in ERROR_KINDS:
            row[f"{kind} median (°)"] = stats[kind]["median"]
            row[f"{kind} p90 (°)"] = stats[kind]["p90"]
        rows.append({**row, "score": float(score)})
    return pd.DataFrame(rows).sort_values("score", kind="stable").reset_index(drop=True)


def broad_triad_statistics(errors: pd.DataFrame) -> dict:
    """Median and 90th percentile of each error kind and group, from :func:`broad_triad_errors`.

    Returns
    -------
    dict
        ``{group: {kind: {"median": …, "p90": …}}}`` (°), the layout of
        :data:`BROAD_TRIAD_ERROR_DEG`.
    """
    if not isinstance(errors, pd.DataFrame) or "group" not in errors:
        raise ValueError("errors must be the DataFrame of broad_triad_errors")
    return {group: {kind: error_statistics(part[f"{kind}_deg"]) for kind in ERROR_KINDS}
            for group, part in errors.groupby("group", sort=False)}


def triad_calibration_table(*, seed: int = 1, n_repetitions: int = 32, broad: dict | None = None,
                            settings: dict | None = None) -> pd.DataFrame:
    """TRIAD's error on BROAD beside the clean and the calibrated simulator, per group and error kind.

    Parameters
    ----------
    seed : int
        Seed of the simulated trials; the default differs from the calibration's (0), so the
        table shows the fit out of sample.
    n_repetitions : int
        Repetitions of each of the four movements.
    broad : dict, optional
        ``{group: {kind: {"median": …, "p90": …}}}``; default the recorded
        :data:`BROAD_TRIAD_ERROR_DEG` (pass :func:`broad_triad_statistics` to use the files).
    settings : dict, optional
        ``{group: Disturbance}``; default :data:`BROAD_CALIBRATED`.

    Returns
    -------
    pandas.DataFrame
        One row per (group, error kind) of :data:`BROAD_GROUPS` × :data:`ERROR_KINDS`
        (MultiIndex ``group``, ``error``); columns ``BROAD median (°)``, ``BROAD p90 (°)``,
        ``clean sim median (°)``, ``clean sim p90 (°)``, ``calibrated sim median (°)``,
        ``calibrated sim p90 (°)``.

    Notes
    -----
    Result with the defaults (seed 1, 32 repetitions; calibration on seed 0), total error,
    median / p90: undisturbed BROAD 10.3° / 66.1°, calibrated simulator 10.4° / 59.6°;
    disturbed BROAD 26.4° / 112.5°, calibrated 30.1° / 103.5°; the clean simulator 0.6° /
    1.9°.  The tests check the calibrated values within :data:`CALIBRATION_TOLERANCE`.
    """
    broad = BROAD_TRIAD_ERROR_DEG if broad is None else broad
    settings = BROAD_CALIBRATED if settings is None else settings
    clean = error_table(simulated_triad_errors(None, rng=np.random.default_rng(seed), n_repetitions=n_repetitions))
    rows = []
    for group in BROAD_GROUPS:
        sim = error_table(simulated_triad_errors(settings[group], rng=np.random.default_rng(seed),
                                                 n_repetitions=n_repetitions))
        for kind in ERROR_KINDS:
            rows.append({"group": group, "error": kind,
                         "BROAD median (°)": broad[group][kind]["median"], "BROAD p90 (°)": broad[group][kind]["p90"],
                         "clean sim median (°)": clean[kind]["median"], "clean sim p90 (°)": clean[kind]["p90"],
                         "calibrated sim median (°)": sim[kind]["median"],
                         "calibrated sim p90 (°)": sim[kind]["p90"]})
    return pd.DataFrame(rows).set_index(["group", "error"])
