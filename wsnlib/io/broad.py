"""BROAD benchmark trials: registry, verified download and loader (:func:`load_broad`).

BROAD (real recordings with optical ground truth)
-------------------------------------------------
:func:`load_broad` reads trials of the Berlin Robust Orientation Estimation Assessment
Dataset:

    D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD—A Benchmark for Robust Inertial
    Orientation Estimation", *Data* 6(7):72, 2021, doi:10.3390/data6070072.
    Data licensed CC BY 4.0 — credit the authors wherever results from it are shown.

The files are the MATLAB versions (``data_mat/<trial>.mat``) of the public repository
github.com/dlaidig/broad, pinned to commit :data:`BROAD_COMMIT`.  :data:`BROAD_REGISTRY` (shipped
as ``wsnlib/registry/broad.tsv``) lists all 39 trials of the dataset and its ``trials.json``,
with the SHA-256 where known (30 trials) and the git blob id of every file (SHA-1 of
``b"blob <size>\\0"`` + content), which verifies the other nine.  :func:`broad_trials` lists the
trials, or with ``present_only=True`` those whose file is in the folder.

Folder, first match wins: the ``data_dir`` argument; else the environment variable
``WSNLIB_BROAD_DIR``; else ``<ROOT>/data/raw/broad/`` (gitignored; ROOT is the checkout,
:data:`wsnlib.paths.ROOT`).  A missing file is downloaded with pooch from
``https://raw.githubusercontent.com/dlaidig/broad/<BROAD_COMMIT>/data_mat/<file>`` into that
folder (unless ``download=False``) and kept only if its SHA-256 (else its git blob id) matches.
Every file, whether downloaded or already there, is hash-checked before it is read; a mismatch
raises ``ValueError`` naming the file and both hashes (a corrupt file is never half-read, and never
silently replaced: delete it to download it again).  The verified hash is remembered per
(path, size, modification time) within the process, so reloading does not rehash.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from wsnlib._files import sha256_of
from wsnlib._validation import as_float_array, check_flag, check_positive
from wsnlib.io.download import RegistryEntry, data_folder, download_verified, git_blob_sha1_of, read_registry

#: Commit of github.com/dlaidig/broad the files are pinned to.
BROAD_COMMIT = "7e2f8189bb4a3ac91eae32c69b6bc87f08a6e2ad"

#: Download address of a file of the dataset's ``data_mat/`` folder.
BROAD_URL = "https://raw.githubusercontent.com/dlaidig/broad/{commit}/data_mat/{filename}"

#: Environment variable naming the folder that holds the BROAD files.
BROAD_DIR_ENV_VAR = "WSNLIB_BROAD_DIR"


#: File name → expected content (:class:`RegistryEntry`) of every file of the dataset's
#: ``data_mat/`` folder at :data:`BROAD_COMMIT`: the 39 trials and ``trials.json``.  The SHA-256
#: is known for 30 trials; the other 9 (13, 17, 19, 20, 22, 23, 37, 38, 39) are verified by
#: their git blob id.  Shipped as ``wsnlib/registry/broad.tsv``.
BROAD_REGISTRY: dict[str, RegistryEntry] = {
    name: RegistryEntry(None if sha == "-" else sha, blob)
    for name, sha, blob in read_registry("broad", ["file", "sha256", "git_blob_sha1"])}

#: Largest tolerated deviation of a reference quaternion's norm from 1.
_BROAD_QUAT_NORM_TOL = 1e-6

#: Verified files: (resolved path, size, mtime_ns) → the expected hash it matched, so
#: reloading does not rehash.
_VERIFIED_HASHES: dict[tuple[str, int, int], str] = {}


def broad_trials(present_only: bool = False, data_dir=None) -> list[str]:
    """Names of the BROAD trials (without ``.mat``), in trial-number order.

    Parameters
    ----------
    present_only : bool
        False (default): all 39 trials of the dataset (each loads if its file is present or can
        be downloaded).  True: only those whose ``.mat`` file is in the folder now (not yet
        hash-checked: :func:`load_broad` does that).
    data_dir : str or pathlib.Path, optional
        Folder looked into when ``present_only``; default see :func:`broad_dir`.
    """
    check_flag(present_only, "present_only")
    names = sorted(name[: -len(".mat")] for name in BROAD_REGISTRY if name.endswith(".mat"))
    if present_only:
        folder = broad_dir(data_dir)
        names = [name for name in names if (folder / f"{name}.mat").is_file()]
    return names


def broad_trial_numbers(trials) -> str:
    """``"02, 07, 16"``: the leading numbers of BROAD trial names, for sentences; ``"none"`` if empty."""
    numbers = [str(trial).split("_", 1)[0] for trial in trials]
    return ", ".join(numbers) or "none"


#: Kinds of motion whose trials are held out together although BROAD names them apart: both
#: shake the sensor at high frequency (tapping, a vibrating phone) without moving its field.
_MERGED_MOTION_GROUPS = {"tapping": "tapping and vibration", "phone vibration": "tapping and vibration"}


def broad_motion_group(trial) -> str:
    """The kind of motion of a BROAD trial, the unit that leave-one-group-out holds out together.

    BROAD repeats each kind of motion in near-duplicate trials (variants A–D, "with breaks", the
    magnet's distance, the duration): ``"02_undisturbed_slow_rotation_B"`` and
    ``"05_undisturbed_slow_rotation_with_breaks_B"`` are both ``"slow rotation"``, the attached
    magnet at 2–5 cm ``"attached magnet"``; tapping and phone vibration form one group.  On the
    17 trials of ``../shared/data/broad`` this gives issue 25's seven groups.

    Parameters
    ----------
    trial : str or int
        A BROAD trial name (with or without ``.mat``) or number.

    Raises
    ------
    ValueError
        Not a BROAD trial.
    """
    words = _broad_trial_name(trial).split("_")[1:]
    words = [w for w in words if w not in ("undisturbed", "disturbed")]
    if words and (len(words[-1]) == 1 or words[-1].endswith(("cm", "s")) and words[-1][0].isdigit()):
        words = words[:-1]  # the variant: A–D, a distance, a duration
    kind = " ".join(words).replace(" with breaks", "")
    return _MERGED_MOTION_GROUPS.get(kind, kind)


def broad_dir(data_dir=None) -> Path:
    """Folder of the BROAD files: ``data_dir``, else ``$WSNLIB_BROAD_DIR``, else ``<ROOT>/data/raw/broad``.

    The folder is not created here (only a download creates it).
    """
    return data_folder(data_dir, BROAD_DIR_ENV_VAR, "broad")


def _broad_trial_name(trial) -> str:
    known = broad_trials()
    if isinstance(trial, bool):
        raise ValueError(f"trial must be a trial name or number, got {trial!r}; known trials: {known}")
    if isinstance(trial, int | np.integer):
        matches = [name for name in known if int(name.split("_", 1)[0]) == int(trial)]
    elif isinstance(trial, str):
        name = trial[: -len(".mat")] if trial.endswith(".mat") else trial
        matches = [name] if name in known else []
    else:
        raise ValueError(f"trial must be a trial name or number, got {type(trial).__name__}; known trials: {known}")
    if not matches:
        raise ValueError(f"unknown BROAD trial {trial!r}; known trials: {known}")
    return matches[0]


def _verify_file(path: Path, expected: RegistryEntry) -> None:
    """Raise ``ValueError`` naming ``path`` and both hashes unless its content is ``expected``.

    Checks the SHA-256 where the registry knows it, else the git blob id.
    """
    if expected.sha256 is not None:
        kind, wanted, compute = "SHA-256", expected.sha256, sha256_of
    elif expected.git_blob_sha1 is not None:
        kind, wanted, compute = "git blob id", expected.git_blob_sha1, git_blob_sha1_of
    else:
        raise ValueError(f"{path}: the registry holds no hash to verify it with")
    stat = path.stat()
    key = (str(path.resolve()), stat.st_size, stat.st_mtime_ns)
    if _VERIFIED_HASHES.get(key) == wanted:
        return
    actual = compute(path)
    if actual != wanted:
        raise ValueError(f"{path}: {kind} is {actual}, expected {wanted} (the file is corrupt, truncated or "
                         f"another version); delete it to download it again")
    _VERIFIED_HASHES[key] = actual


def _forget_verified(path: Path) -> None:
    """Drop what :func:`_verify_file` remembers of ``path``, so that the next check hashes its content."""
    resolved = str(path.resolve())
    for key in [key for key in _VERIFIED_HASHES if key[0] == resolved]:
        del _VERIFIED_HASHES[key]


def broad_file(filename: str, data_dir=None, *, download: bool = True, downloader=None) -> Path:
    """Path of a verified BROAD file, downloading it first if it is missing.

    Parameters
    ----------
    filename : str
        A key of :data:`BROAD_REGISTRY`, e.g. ``"02_undisturbed_slow_rotation_B.mat"``.
    data_dir : str or pathlib.Path, optional
        Folder; default see :func:`broad_dir`.
    download : bool
        If False, a missing file raises ``FileNotFoundError`` instead of being downloaded.
    downloader : callable, optional
        Passed on to :func:`pooch.retrieve`: called as ``downloader(url, output_file, pooch)``
        and must write the file at ``url`` to the path ``output_file`` (default: pooch's HTTP
        downloader).  The tests inject a local copier here.

    Returns
    -------
    pathlib.Path
        The file, whose SHA-256 (or, where the registry has none, git blob id) matches the
        registry.

    Raises
    ------
    ValueError
        Unknown ``filename``; or a hash mismatch, of a file already present or of a download
        (a failed download leaves no file behind).
    FileNotFoundError
        The file is missing and ``download`` is False.
    OSError
        The download itself failed (no network, HTTP error).
    """
    if filename not in BROAD_REGISTRY:
        raise ValueError(f"unknown BROAD file {filename!r}; known files: {sorted(BROAD_REGISTRY)}")
    expected = BROAD_REGISTRY[filename]
    folder = broad_dir(data_dir)
    path = folder / filename
    if not path.exists():
        url = BROAD_URL.format(commit=BROAD_COMMIT, filename=filename)
        if not download:
            raise FileNotFoundError(f"{path} does not exist; download it from {url}, point ${BROAD_DIR_ENV_VAR} or "
                                    f"data_dir at a folder holding it, or call with download=True")
        download_verified(url, path, expected, downloader, env_var=BROAD_DIR_ENV_VAR)
    _verify_file(path, expected)
    return path


@dataclass(frozen=True, eq=False)
class BroadTrial:
    """One BROAD trial: IMU signals and the optical reference orientation, sampled together.

    The arrays are read-only copies.  Credit: Laidig et al., BROAD, Data 6(7):72, 2021
    (CC BY 4.0).

    Attributes
    ----------
    name : str
        Trial name, e.g. ``"02_undisturbed_slow_rotation_B"``.
    fs : float
        Sampling rate (Hz); 2000/7 ≈ 285.714 Hz in the files (stored to full double precision).
    time_s : numpy.ndarray, shape (T,)
        Sample times (s), ``k / fs`` (the files carry no time stamps).
    gyr : numpy.ndarray, shape (T, 3)
        Angular rate, IMU body frame (rad/s), file key ``imu_gyr``.
    acc : numpy.ndarray, shape (T, 3)
        Specific force, IMU body frame (m/s², +g upward at rest), file key ``imu_acc``.
    mag : numpy.ndarray, shape (T, 3)
        Magnetic field, IMU body frame (µT), file key ``imu_mag``.
    quat_ref : numpy.ndarray, shape (T, 4)
        Optical reference orientation ``[w, x, y, z]``, body → ENU, unit norm (file key
        ``opt_quat``, already aligned to the IMU by the dataset's authors).  Rows are NaN
        where the markers were lost; they are kept NaN (never interpolated).
    movement : numpy.ndarray of bool, shape (T,)
        Samples of the movement phase, the ones BROAD's errors are computed on.
    info : str
        The file's description text.
    """

    name: str
    fs: float
    time_s: np.ndarray = field(repr=False)
    gyr: np.ndarray = field(repr=False)
    acc: np.ndarray = field(repr=False)
    mag: np.ndarray = field(repr=False)
    quat_ref: np.ndarray = field(repr=False)
    movement: np.ndarray = field(repr=False)
    info: str = field(default="", repr=False)

    #: Attribute → key in the .mat file, for error messages.
    _FILE_KEYS = {"gyr": "imu_gyr", "acc": "imu_acc", "mag": "imu_mag", "quat_ref": "opt_quat",
                  "movement": "movement"}

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"name must be a non-empty string, got {self.name!r}")
        where = f"BROAD trial {self.name!r}"
        object.__setattr__(self, "fs", check_positive(self.fs, f"{where}: fs"))
        time_s = self._frozen(as_float_array(self.time_s, f"{where}: time_s"))
        if time_s.ndim != 1 or time_s.size < 2:
            raise ValueError(f"{where}: time_s must be 1-D with at least 2 samples, got shape {time_s.shape}")
        if np.any(np.diff(time_s) <= 0.0):
            raise ValueError(f"{where}: time_s must be strictly increasing")
        object.__setattr__(self, "time_s", time_s)
        n = time_s.size
        for attr in ("gyr", "acc", "mag"):
            label = f"{where}: {attr} (file key {self._FILE_KEYS[attr]!r})"
            arr = np.asarray(getattr(self, attr))
            if arr.shape != (n, 3):
                raise ValueError(f"{label} must have shape {(n, 3)}, got {arr.shape}")
            object.__setattr__(self, attr, self._frozen(as_float_array(arr, label)))
        label = f"{where}: quat_ref (file key 'opt_quat')"
        quat = np.array(self.quat_ref, dtype=float)
        if quat.shape != (n, 4):
            raise ValueError(f"{label} must have shape {(n, 4)}, got {quat.shape}")
        nan_rows = np.isnan(quat).any(axis=-1)
        if np.any(np.isinf(quat)) or np.any(nan_rows & ~np.isnan(quat).all(axis=-1)):
            raise ValueError(f"{label}: rows must be finite or entirely NaN (lost markers)")
        norm_error = np.abs(np.linalg.norm(quat[~nan_rows], axis=-1) - 1.0)
        if np.any(norm_error > _BROAD_QUAT_NORM_TOL):
            sample = int(np.flatnonzero(~nan_rows)[np.argmax(norm_error)])
            raise ValueError(f"{label}: not a unit quaternion at sample {sample}")
        object.__setattr__(self, "quat_ref", self._frozen(quat))
        movement = np.asarray(self.movement)
        if movement.dtype != np.bool_ or movement.shape != (n,):
            raise ValueError(f"{where}: movement must be a boolean array of shape {(n,)}, got {movement.dtype} "
                             f"{movement.shape}")
        object.__setattr__(self, "movement", self._frozen(movement))
        if not isinstance(self.info, str):
            raise ValueError(f"{where}: info must be a string")

    @staticmethod
    def _frozen(arr: np.ndarray) -> np.ndarray:
        arr = np.array(arr, copy=True)
        arr.setflags(write=False)
        return arr

    @property
    def n_samples(self) -> int:
        """Number of samples T."""
        return self.time_s.size

    @property
    def reference_valid(self) -> np.ndarray:
        """Boolean ``(T,)``: samples where the optical reference exists (not NaN)."""
        return ~np.isnan(self.quat_ref[:, 0])


def load_broad(trial, data_dir=None, *, download: bool = True, downloader=None) -> BroadTrial:
    """Load one BROAD trial (Laidig et al. 2021, CC BY 4.0), downloading and verifying it if needed.

    Parameters
    ----------
    trial : str or int
        Trial name as in :func:`broad_trials` (with or without ``.mat``), or its number
        (``2`` for ``"02_undisturbed_slow_rotation_B"``).
    data_dir : str or pathlib.Path, optional
        Folder of the files; default ``$WSNLIB_BROAD_DIR``, else ``<ROOT>/data/raw/broad``.
    download : bool
        Download a missing file (pooch, from the repository pinned to :data:`BROAD_COMMIT`).
    downloader : callable, optional
        Replaces pooch's HTTP downloader; see :func:`broad_file`.

    Returns
    -------
    BroadTrial
        Signals in the IMU body frame: ``gyr`` rad/s, ``acc`` m/s², ``mag`` µT, ``quat_ref``
        ``[w, x, y, z]`` body → ENU (NaN rows where the optical markers were lost),
        ``movement`` bool, at ``fs`` = 2000/7 ≈ 285.714 Hz.

    Raises
    ------
    ValueError
        Unknown trial (the message lists the known ones); SHA-256 mismatch (naming the file,
        the expected and the actual hash); a missing key, a wrong shape or non-finite IMU
        signals (naming the trial and the key).
    FileNotFoundError, OSError
        See :func:`broad_file`.
    """
    import scipy.io

    name = _broad_trial_name(trial)
    path = broad_file(f"{name}.mat", data_dir, download=download, downloader=downloader)
    try:
        mat = scipy.io.loadmat(path)
    except Exception as exc:  # any reader failure: check the content before blaming the reader
        # A file replaced after it was verified (same size and mtime) passes the remembered check:
        # hash it again, which names a changed file; a file whose content is right but unreadable is named here.
        _forget_verified(path)
        _verify_file(path, BROAD_REGISTRY[f"{name}.mat"])
        raise ValueError(f"BROAD trial {name!r}: {path} matches the registry but cannot be read as a MATLAB "
                         f"file ({type(exc).__name__}: {exc})") from exc
    missing = [key for key in ("imu_gyr", "imu_acc", "imu_mag", "opt_quat", "movement", "sampling_rate")
               if key not in mat]
    if missing:
        raise ValueError(f"BROAD trial {name!r} ({path}) lacks the key(s) {missing}")
    rate = np.asarray(mat["sampling_rate"], dtype=float)
    if rate.size != 1:
        raise ValueError(f"BROAD trial {name!r}: key 'sampling_rate' must be a scalar, got shape {rate.shape}")
    fs = float(rate.reshape(()))
    movement_raw = np.asarray(mat["movement"]).reshape(-1)
    if not np.all((movement_raw == 0) | (movement_raw == 1)):
        raise ValueError(f"BROAD trial {name!r}: key 'movement' must hold only 0 and 1")
    n_samples = np.asarray(mat["imu_gyr"]).shape[0]
    info = mat.get("info")
    info_text = str(np.asarray(info).reshape(-1)[0]) if info is not None and np.asarray(info).size else ""
    time_s = np.arange(n_samples) / check_positive(fs, f"BROAD trial {name!r}: sampling_rate")
    return BroadTrial(name=name, fs=fs, time_s=time_s, gyr=mat["imu_gyr"], acc=mat["imu_acc"], mag=mat["imu_mag"],
                      quat_ref=mat["opt_quat"], movement=movement_raw.astype(bool), info=info_text)
