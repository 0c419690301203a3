"""What the loss-tolerance study runs on: one IMU with its reference, from a BROAD trial or a recording file.

A *unit* of the study (:class:`StudyRecording`) is one IMU's signals, its reference orientation
and the samples to score, at the rate it was recorded at (its own ``fs``; nothing is assumed
about the rate).  Every method, loss mask, metric and trace of the study uses the unit's ``fs``.

Where units come from (:func:`load_recordings`, the one door):

* a BROAD trial name (``"02_undisturbed_slow_rotation_B"``): one unit, named as the trial,
  resampled to :data:`BROAD_FS` (paper 001's 50 Hz) by :func:`wsnlib.io.resample.resample_broad`;
  BROAD's ``movement`` marks the samples scored;
* a recording file of :mod:`wsnlib.io.recording` (``.csv``, or its ``.json`` sidecar): one unit
  per node with a reference (:func:`from_recording`), named ``"<file stem>/<node>"``, at the
  file's ``fs_hz``; the file's ``movement`` column marks the samples scored, or, without one,
  every sample with a reference.

Units of one recording (its nodes) share the movement and the session: they are not
independent, so the study's leave-one-out tuning holds out a whole recording at once
(``source``, :func:`wsnlib.loto.leave_one_out_choice` with groups).  With a single recording
there is nothing to tune on; the study then runs every method with its default setting
(:attr:`~wsnlib.studies.loss_tolerance.registry.Method.default`) and says so.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from wsnlib._validation import as_float_array, check_positive
from wsnlib.io.broad import BroadTrial, broad_motion_group, broad_trials, load_broad
from wsnlib.io.health import RecordingHealth, recording_health
from wsnlib.io.recording import Recording, read_recording
from wsnlib.io.resample import resample_broad
from wsnlib.quaternion import as_quat_with_gaps

#: Rate (Hz) BROAD trials are resampled to by default: paper 001's 50 Hz.
BROAD_FS = 50.0
#: Largest deviation of a time step from ``1 / fs``, as a fraction of ``1 / fs``, that a recording
#: file may have to be studied at its ``fs`` (a dropped or repeated sample is far beyond it).
REGULAR_STEP_TOLERANCE = 0.05
#: File suffixes that :func:`load_recordings` reads as recording files (anything else is a BROAD name).
RECORDING_SUFFIXES = (".csv", ".json")


@dataclasses.dataclass(frozen=True, eq=False)
class StudyRecording:
    """One IMU with its reference: what the study runs every method on.

    Attributes
    ----------
    source : str
        The recording it comes from (BROAD trial name or file stem): leave-one-out holds out
        every unit of a source together.
    node : str
        The IMU: the node's name in a recording file; ``"imu"`` for a BROAD trial.
    fs : float
        Sampling rate (Hz) of every signal below.
    gyr, acc, mag : numpy.ndarray, shape (T, 3)
        Angular rate (rad/s), specific force (m/s²), magnetic field (µT), body frame.
    quat_ref : numpy.ndarray, shape (T, 4)
        Reference orientation ``[w, x, y, z]`` (body → ENU); rows of NaN where it is missing.
    movement : numpy.ndarray of bool, shape (T,)
        Samples scored (BROAD's ``movement``, a file's ``movement`` column, or every sample
        with a reference); missing-reference samples are never scored.
    """

    source: str
    node: str
    fs: float
    gyr: np.ndarray = dataclasses.field(repr=False)
    acc: np.ndarray = dataclasses.field(repr=False)
    mag: np.ndarray = dataclasses.field(repr=False)
    quat_ref: np.ndarray = dataclasses.field(repr=False)
    movement: np.ndarray = dataclasses.field(repr=False)

    def __post_init__(self):
        where = f"study recording {self.source!r}, node {self.node!r}"
        object.__setattr__(self, "fs", check_positive(self.fs, f"{where}: fs"))
        n = np.shape(self.gyr)[0] if np.ndim(self.gyr) else 0
        for name in ("gyr", "acc", "mag"):
            arr = as_float_array(getattr(self, name), f"{where}: {name}", last_dim=3)
            if arr.shape != (n, 3):
                raise ValueError(f"{where}: {name} must have shape {(n, 3)}, got {arr.shape}")
            object.__setattr__(self, name, arr)
        quat = as_quat_with_gaps(self.quat_ref, f"{where}: quat_ref")
        if quat.shape != (n, 4):
            raise ValueError(f"{where}: quat_ref must have shape {(n, 4)}, got {quat.shape}")
        object.__setattr__(self, "quat_ref", quat)
        movement = np.asarray(self.movement)
        if movement.dtype != np.bool_ or movement.shape != (n,):
            raise ValueError(f"{where}: movement must be a boolean array of shape {(n,)}, got {movement.dtype} "
                             f"{movement.shape}")
        if not np.any(movement & self.reference_valid):
            raise ValueError(f"{where}: no sample is both movement and with a reference: nothing to score")
        object.__setattr__(self, "movement", movement)

    @property
    def n_samples(self) -> int:
        """Number of samples T."""
        return self.gyr.shape[0]

    @property
    def reference_valid(self) -> np.ndarray:
        """Boolean ``(T,)``: samples where the reference exists (not NaN)."""
        return ~np.isnan(self.quat_ref[:, 0])


def from_broad(trial: BroadTrial) -> StudyRecording:
    """A (resampled) BROAD trial as one unit: source the trial's name, node ``"imu"``, its own ``fs``."""
    if not isinstance(trial, BroadTrial):
        raise ValueError(f"trial must be a BroadTrial (wsnlib.io.broad.load_broad), got {type(trial).__name__}")
    return StudyRecording(source=trial.name, node="imu", fs=trial.fs, gyr=trial.gyr, acc=trial.acc, mag=trial.mag,
                          quat_ref=trial.quat_ref, movement=trial.movement)


def check_regular_time(time_s, fs: float, where: str) -> None:
    """``ValueError`` unless every step of ``time_s`` (s) is ``1 / fs`` within :data:`REGULAR_STEP_TOLERANCE`.

    The study places loss packets, gaps and rates by sample index at ``fs``: a recording with
    dropped samples or a drifting clock would be scored at the wrong times.
    """
    fs = check_positive(fs, f"{where}: fs")
    steps = np.diff(np.asarray(time_s, dtype=float)) * fs
    off = np.abs(steps - 1.0) > REGULAR_STEP_TOLERANCE
    if np.any(off):
        k = int(np.argmax(off))
        raise ValueError(f"{where}: time stamps are not regular at fs = {fs:g} Hz: the step after sample {k} is "
                         f"{steps[k] / fs:.6g} s, expected {1 / fs:.6g} s (± {100 * REGULAR_STEP_TOLERANCE:g} %); "
                         f"{int(off.sum())} step(s) are off. Resample the recording onto a regular grid first "
                         f"(wsnlib.io.resample_timestamps), then study it at that rate")


def from_recording(recording: Recording, name: str) -> dict[str, StudyRecording]:
    """The units of a recording: one per node with a reference, named ``"<name>/<node>"``.

    Parameters
    ----------
    recording : wsnlib.io.recording.Recording
        At its own ``fs``, with regular time stamps (:func:`check_regular_time`).
    name : str
        The recording's name (the file stem for files): each unit's ``source``.

    Returns
    -------
    dict name → StudyRecording
        In node order.  A node's movement mask is the recording's ``movement`` (format version
        2) where given, else every sample with a reference.  Nodes without any scorable sample
        (no reference, or no reference during movement) are left out.

    Raises
    ------
    ValueError
        No reference at all (``quat_true`` None), no node with a scorable sample, or irregular
        time stamps.
    """
    if not isinstance(recording, Recording):
        raise ValueError(f"recording must be a wsnlib.io.recording.Recording, got {type(recording).__name__}")
    if recording.quat_true is None:
        raise ValueError(f"recording {name!r} has no reference orientation (quat_* columns): the study scores "
                         f"against it")
    check_regular_time(recording.time_s, recording.fs, f"recording {name!r}")
    valid = recording.reference_valid
    movement = valid if recording.movement is None else recording.movement
    units = {f"{name}/{node}": StudyRecording(source=name, node=node, fs=recording.fs, gyr=recording.gyr[i],
                                              acc=recording.acc[i], mag=recording.mag[i],
                                              quat_ref=recording.quat_true[i], movement=movement[i])
             for i, node in enumerate(recording.nodes) if np.any(movement[i] & valid[i])}
    if not units:
        raise ValueError(f"recording {name!r}: no node has a sample with a reference during movement")
    return units


def units_health(units) -> RecordingHealth:
    """:func:`wsnlib.io.health.recording_health` of every study unit, in one table.

    What the study runs before any method sees a unit (:func:`~wsnlib.studies.loss_tolerance.
    evaluate` keeps it as ``result.health``; the command line prints its findings first): the
    repeated samples, the reference against the gyroscope (marker swaps), the magnetometer's norm
    spread and disturbed share, and the units, each unit at its own ``fs`` (the time base itself
    is regular by construction: BROAD is resampled, a file's steps are checked by
    :func:`check_regular_time`).

    Parameters
    ----------
    units : mapping name → StudyRecording
        Or any object with ``fs`` (Hz), ``gyr``, ``acc``, ``mag`` ``(T, 3)``, ``quat_ref``
        ``(T, 4)``.

    Returns
    -------
    RecordingHealth
        ``table`` indexed by unit name (the columns of :func:`~wsnlib.io.health.recording_health`);
        ``findings`` each prefixed with its unit's name.
    """
    tables, findings = [], []
    for name, unit in units.items():
        fs = check_positive(getattr(unit, "fs", None), f"units[{name!r}].fs")
        n = np.shape(unit.gyr)[0]
        health = recording_health(np.arange(n) / fs, unit.gyr, unit.acc, unit.mag, unit.quat_ref, fs=fs,
                                  names=[name])
        tables.append(health.table)
        findings += [f"{name}: {sentence}" for sentence in health.findings]
    if not tables:
        raise ValueError("units must hold at least one unit")
    return RecordingHealth(table=pd.concat(tables), findings=tuple(findings))


def all_broad(names) -> bool:
    """Whether every name is a BROAD trial's (:func:`wsnlib.io.broad.broad_trials`): the sentences
    name BROAD's groups of trials and say "BROAD" only then."""
    known = set(broad_trials())
    names = [str(name) for name in names]
    return bool(names) and all(name in known for name in names)


def holdout_groups(units) -> dict[str, str]:
    """Which units leave-one-group-out holds out together: unit name → group label.

    BROAD trials (all units BROAD's, :func:`all_broad`, of at least two kinds): their kind of
    motion (:func:`wsnlib.io.broad.broad_motion_group`), so that near-duplicate trials never sit
    on both sides of a fold.  Otherwise each unit's recording (``source``): the nodes of one
    recording are held out together.

    Parameters
    ----------
    units : mapping name → recording
        As :func:`load_recordings` returns (objects with ``source``; a name is its own source
        otherwise).
    """
    names = [str(name) for name in units]
    if all_broad(names):
        kinds = {name: broad_motion_group(name) for name in names}
        if len(set(kinds.values())) >= 2:
            return kinds
    return {name: str(getattr(unit, "source", name)) for name, unit in zip(names, units.values(), strict=True)}


def _is_file(source) -> bool:
    return isinstance(source, Path) or str(source).lower().endswith(RECORDING_SUFFIXES)


def load_recordings(sources, *, broad_fs: float = BROAD_FS, download: bool = False,
                    progress: bool = True) -> dict[str, StudyRecording]:
    """The study's units from BROAD trial names and recording files (mixed freely).

    Parameters
    ----------
    sources : iterable of str or pathlib.Path
        A path (or a name ending in ``.csv`` or ``.json``) is a recording file of
        :mod:`wsnlib.io.recording`, read by :func:`~wsnlib.io.recording.read_recording` and cut
        into units by :func:`from_recording` (``"<file stem>/<node>"``, at the file's rate);
        anything else is a BROAD trial name, loaded by :func:`wsnlib.io.broad.load_broad` (from
        ``$WSNLIB_BROAD_DIR``; downloaded and hash-checked only with ``download``), resampled to
        ``broad_fs`` and named as the trial.
    broad_fs : float
        Rate (Hz) BROAD trials are resampled to (default :data:`BROAD_FS`, paper 001's 50 Hz).
    download : bool
    progress : bool
        A tqdm progress bar over the sources.

    Returns
    -------
    dict name → StudyRecording
        In the order of ``sources``.

    Raises
    ------
    ValueError
        No source, a name given twice (two files with the same stem), or whatever the readers
        raise (naming the file).
    """
    sources = list(sources)
    if not sources:
        raise ValueError("sources must name at least one BROAD trial or recording file")
    units: dict[str, StudyRecording] = {}
    for source in tqdm(sources, desc="load", disable=not progress):
        if _is_file(source):
            path = Path(source)
            new = from_recording(read_recording(path), path.stem)
        else:
            new = {str(source): from_broad(resample_broad(load_broad(source, download=download), broad_fs))}
        twice = sorted(set(new) & set(units))
        if twice:
            raise ValueError(f"sources give {twice} twice (two files with the same name, or a trial listed twice); "
                             f"rename one")
        units.update(new)
    return units


def notebook_sources(trials="all", recordings=None, *, quick: bool = False) -> list:
    """What notebooks 05 and 10 load: the recording files, or the BROAD trials (exactly one of the two).

    Parameters
    ----------
    trials : "all" or list of str
        BROAD trial names; ``"all"``: every trial present in the data folder, or, when none is,
        all 39 (downloaded).
    recordings : list of str, optional
        Recording files (``.csv`` or their ``.json`` sidecars); given, ``trials`` must be left
        at ``"all"``.
    quick : bool
        Only the first two BROAD trials (leave-one-out needs two); recording files are all kept.

    Raises
    ------
    ValueError
        Both ``trials`` and ``recordings`` given, or an empty or non-list ``recordings``.
    """
    if recordings is not None:
        if trials != "all":
            raise ValueError(f"give either trials (BROAD) or recordings (files), not both; got trials={trials!r} "
                             f"and recordings={recordings!r}")
        if isinstance(recordings, str | Path) or len(recordings) == 0:
            raise ValueError(f"recordings must be a non-empty list of recording files, got {recordings!r}")
        return [str(path) for path in recordings]
    names = broad_trials(present_only=True) if trials == "all" else list(trials)
    if not names:  # no trial in the folder (a fresh clone without ../shared): every trial, downloaded
        names = broad_trials()
    return names[:2] if quick else names
