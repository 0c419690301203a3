"""BROAD loader: registry, folder resolution, hash checks, (fake) downloads, and the trial itself.

The trials are read from ``$WSNLIB_BROAD_DIR`` or the shared folder next to the checkout
(``../shared/data/broad``, as the Makefile does); tests needing a file skip without one.
Downloads are tested with a local copier in place of pooch's HTTP downloader (no network).
"""

import dataclasses
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from wsnlib import datasets, paths
from wsnlib import quaternion as Q

TRIAL = "02_undisturbed_slow_rotation_B"
TRIAL_FILE = f"{TRIAL}.mat"
SOURCE_DIR = Path(os.environ.get(datasets.BROAD_DIR_ENV_VAR) or paths.ROOT.parent / "shared" / "data" / "broad")

needs_files = pytest.mark.skipif(
    not (SOURCE_DIR / TRIAL_FILE).exists() or not (SOURCE_DIR / "trials.json").exists(),
    reason=f"BROAD files not found in {SOURCE_DIR}",
)


@pytest.fixture(scope="module")
def trial():
    if not (SOURCE_DIR / TRIAL_FILE).exists():
        pytest.skip(f"BROAD files not found in {SOURCE_DIR}")
    return datasets.load_broad(TRIAL, SOURCE_DIR, download=False)


class CopyDownloader:
    """Stands in for pooch's downloader: copies ``<SOURCE_DIR>/<file name of url>``, optionally truncated."""

    def __init__(self, truncate: int | None = None):
        self.truncate = truncate
        self.urls = []

    def __call__(self, url, output_file, pooch):
        self.urls.append(url)
        data = (SOURCE_DIR / url.rsplit("/", 1)[-1]).read_bytes()
        if self.truncate is not None:
            data = data[: self.truncate]
        Path(output_file).write_bytes(data)


def test_registry_lists_six_trials_and_trials_json():
    names = datasets.broad_trials()
    assert len(names) == 6 and names[0] == TRIAL and names == sorted(names)
    assert "trials.json" in datasets.BROAD_REGISTRY
    assert all(re.fullmatch(r"[0-9a-f]{64}", h) for h in datasets.BROAD_REGISTRY.values())
    readme = SOURCE_DIR / "README.md"
    if readme.exists():  # the registry agrees with the sums published next to the files
        published = dict((name, digest) for digest, name in re.findall(r"^([0-9a-f]{64})\s+(\S+)$",
                                                                       readme.read_text(), flags=re.M))
        assert published == datasets.BROAD_REGISTRY
        assert datasets.BROAD_COMMIT in readme.read_text()


@pytest.mark.parametrize("spec", [2, np.int64(2), TRIAL, TRIAL_FILE])
def test_trial_given_by_name_or_number(spec):
    assert datasets._broad_trial_name(spec) == TRIAL


@pytest.mark.parametrize("spec", [1, 99, "01_undisturbed_slow_rotation_A", "02", True, 2.0, None])
def test_unknown_trial_lists_the_known_ones(spec):
    with pytest.raises(ValueError, match="known trials: .*02_undisturbed_slow_rotation_B"):
        datasets.load_broad(spec, download=False)


def test_folder_resolution(tmp_path, monkeypatch):
    monkeypatch.delenv(datasets.BROAD_DIR_ENV_VAR, raising=False)
    assert datasets.broad_dir() == paths.ROOT / "data" / "raw" / "broad"
    monkeypatch.setenv(datasets.BROAD_DIR_ENV_VAR, str(tmp_path / "env"))
    assert datasets.broad_dir() == tmp_path / "env"
    assert datasets.broad_dir(tmp_path / "arg") == tmp_path / "arg"
    assert not (tmp_path / "env").exists()  # resolving creates nothing


def test_missing_file_without_download(tmp_path):
    with pytest.raises(FileNotFoundError, match=re.escape(str(tmp_path / TRIAL_FILE))):
        datasets.load_broad(TRIAL, tmp_path, download=False)


def test_unknown_file_name():
    with pytest.raises(ValueError, match="unknown BROAD file"):
        datasets.broad_file("01_undisturbed_slow_rotation_A.mat")


@needs_files
def test_download_goes_to_the_pinned_url_and_is_verified(tmp_path, monkeypatch):
    folder = tmp_path / "new" / "broad"
    monkeypatch.setenv(datasets.BROAD_DIR_ENV_VAR, str(folder))
    fake = CopyDownloader()
    loaded = datasets.load_broad(2, downloader=fake)
    assert fake.urls == [
        f"https://raw.githubusercontent.com/dlaidig/broad/{datasets.BROAD_COMMIT}/data_mat/{TRIAL_FILE}"
    ]
    assert (folder / TRIAL_FILE).read_bytes() == (SOURCE_DIR / TRIAL_FILE).read_bytes()
    assert loaded.name == TRIAL and loaded.n_samples == 53240
    datasets.load_broad(2, downloader=fake)  # present now: no second download
    assert len(fake.urls) == 1
    info = datasets.broad_trial_info(downloader=fake)
    assert TRIAL in info["trials"] and len(fake.urls) == 2


@needs_files
@pytest.mark.parametrize("name", [TRIAL_FILE, "trials.json"])
def test_truncated_download_fails_and_leaves_nothing(tmp_path, name):
    fake = CopyDownloader(truncate=1000)
    with pytest.raises(ValueError, match=re.escape(name)) as info:
        datasets.broad_file(name, tmp_path, downloader=fake)
    assert datasets.BROAD_REGISTRY[name] in str(info.value)
    assert list(tmp_path.iterdir()) == []  # neither the bad file nor pooch's temporary copy


def test_failed_connection_is_an_os_error_with_a_hint(tmp_path):
    def offline(url, output_file, pooch):
        raise ConnectionError("network unreachable")

    with pytest.raises(OSError, match="WSNLIB_BROAD_DIR"):
        datasets.broad_file("trials.json", tmp_path, downloader=offline)
    assert not (tmp_path / "trials.json").exists()


@needs_files
@pytest.mark.parametrize("damage", ["flip", "truncate"])
def test_corrupt_existing_file_is_refused_not_replaced(tmp_path, damage):
    path = tmp_path / TRIAL_FILE
    data = bytearray((SOURCE_DIR / TRIAL_FILE).read_bytes())
    if damage == "flip":
        data[len(data) // 2] ^= 0xFF
    else:
        data = data[: len(data) // 2]
    path.write_bytes(bytes(data))
    fake = CopyDownloader()
    with pytest.raises(ValueError, match="SHA-256") as info:
        datasets.load_broad(TRIAL, tmp_path, downloader=fake)
    message = str(info.value)
    assert str(path) in message and datasets.BROAD_REGISTRY[TRIAL_FILE] in message
    assert datasets.sha256_of(path) in message  # the actual hash too
    assert fake.urls == [] and path.read_bytes() == bytes(data)


@needs_files
def test_hash_is_cached_per_path_size_and_mtime(tmp_path, monkeypatch):
    path = tmp_path / "trials.json"
    shutil.copyfile(SOURCE_DIR / "trials.json", path)
    calls = []
    real = datasets.sha256_of
    monkeypatch.setattr(datasets, "sha256_of", lambda p: calls.append(p) or real(p))
    datasets.broad_file("trials.json", tmp_path, download=False)
    datasets.broad_file("trials.json", tmp_path, download=False)
    assert len(calls) == 1
    # a change after verification is caught: same size, new content and mtime
    original = path.read_bytes()
    path.write_bytes(original.replace(b"slow", b"SLOW", 1))
    stat = path.stat()
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))
    with pytest.raises(ValueError, match="SHA-256"):
        datasets.broad_file("trials.json", tmp_path, download=False)


def test_trial_content(trial):
    n = 53240
    assert trial.name == TRIAL
    assert trial.fs == 2000 / 7  # stored to full double precision
    assert trial.time_s.shape == (n,) and trial.time_s[1] == pytest.approx(7 / 2000)
    for name in ("gyr", "acc", "mag"):
        arr = getattr(trial, name)
        assert arr.shape == (n, 3) and np.all(np.isfinite(arr))
    assert trial.quat_ref.shape == (n, 4) and trial.movement.shape == (n,)
    assert trial.movement.dtype == np.bool_ and trial.movement.sum() == 32280
    gaps = ~trial.reference_valid
    assert gaps.sum() == 1706 and np.all(np.isnan(trial.quat_ref[gaps]))
    assert np.allclose(np.linalg.norm(trial.quat_ref[~gaps], axis=-1), 1.0)
    assert TRIAL in trial.info and "µT" in trial.info
    assert repr(trial) == f"BroadTrial(name={TRIAL!r}, fs={2000 / 7!r})"


def test_trial_frames_and_units(trial):
    """At rest, the reference turns acc into +g along ENU up and mag into north-and-down."""
    rest = trial.reference_valid & ~trial.movement
    acc_earth = Q.rotate(trial.quat_ref[rest], trial.acc[rest]).mean(axis=0)
    np.testing.assert_allclose(acc_earth, [0.0, 0.0, 9.81], atol=0.1)
    mag_earth = Q.rotate(trial.quat_ref[rest], trial.mag[rest]).mean(axis=0)
    assert abs(mag_earth[0]) < 1.0 and 10.0 < mag_earth[1] < 25.0 and -50.0 < mag_earth[2] < -30.0  # µT
    assert np.abs(trial.gyr[rest]).mean() < 0.05  # rad/s


def test_trial_is_frozen_and_read_only(trial):
    with pytest.raises(dataclasses.FrozenInstanceError):
        trial.fs = 50.0
    with pytest.raises(ValueError, match="read-only"):
        trial.gyr[0, 0] = 1.0


def test_trial_validation_names_trial_and_key(trial):
    gyr = np.array(trial.gyr)
    gyr[10, 1] = np.nan
    with pytest.raises(ValueError, match=r"'02_undisturbed_slow_rotation_B'.*'imu_gyr'.*NaN"):
        dataclasses.replace(trial, gyr=gyr)
    with pytest.raises(ValueError, match=r"'imu_mag'.*shape"):
        dataclasses.replace(trial, mag=trial.mag[:, :2])
    quat = np.array(trial.quat_ref)
    quat[np.flatnonzero(trial.reference_valid)[0], 2] = np.nan
    with pytest.raises(ValueError, match="entirely NaN"):
        dataclasses.replace(trial, quat_ref=quat)
    with pytest.raises(ValueError, match="movement"):
        dataclasses.replace(trial, movement=trial.movement.astype(np.uint8))
