"""BROAD loader: registry, folder resolution, hash checks, (fake) downloads, and the trial itself.

The trials are read from ``$WSNLIB_BROAD_DIR`` or the shared folder next to the checkout
(``../shared/data/broad``, as the Makefile does); tests needing a file skip without one.
Downloads are tested with a local copier in place of pooch's HTTP downloader (no network).
"""

import dataclasses
import json
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from _calibration import BROAD_CALIBRATION_TRIALS

from wsnlib import paths
from wsnlib import quaternion as Q
from wsnlib.io import broad as broad_io
from wsnlib.io import download

TRIAL = "02_undisturbed_slow_rotation_B"
TRIAL_FILE = f"{TRIAL}.mat"
SOURCE_DIR = Path(os.environ.get(broad_io.BROAD_DIR_ENV_VAR) or paths.ROOT.parent / "shared" / "data" / "broad")

needs_files = pytest.mark.skipif(
    not (SOURCE_DIR / TRIAL_FILE).exists() or not (SOURCE_DIR / "trials.json").exists(),
    reason=f"BROAD files not found in {SOURCE_DIR}",
)


@pytest.fixture(scope="module")
def trial():
    if not (SOURCE_DIR / TRIAL_FILE).exists():
        pytest.skip(f"BROAD files not found in {SOURCE_DIR}")
    return broad_io.load_broad(TRIAL, SOURCE_DIR, download=False)


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


SHARED_TRIALS = list(BROAD_CALIBRATION_TRIALS)  # the 17 trials of ../shared/data/broad (see its README)
BLOB_ONLY = {13, 17, 19, 20, 22, 23, 37, 38, 39}  # trials whose SHA-256 the registry lacks


def test_registry_lists_all_39_trials_and_trials_json():
    names = broad_io.broad_trials()
    assert len(names) == 39 and names == sorted(names)
    assert [int(name[:2]) for name in names] == list(range(1, 40))
    assert names[0] == "01_undisturbed_slow_rotation_A" and names[1] == TRIAL and names[-1] == "39_disturbed_mixed"
    assert set(broad_io.BROAD_REGISTRY) == {f"{name}.mat" for name in names} | {"trials.json"}
    for name, entry in broad_io.BROAD_REGISTRY.items():
        assert re.fullmatch(r"[0-9a-f]{40}", entry.git_blob_sha1), name
        if name.endswith(".mat") and int(name[:2]) in BLOB_ONLY:
            assert entry.sha256 is None, name
        else:
            assert re.fullmatch(r"[0-9a-f]{64}", entry.sha256), name


def test_registry_agrees_with_the_published_sums():
    readme, registry = SOURCE_DIR / "README.md", SOURCE_DIR / "REGISTRY.tsv"
    if not readme.exists() or not registry.exists():
        pytest.skip(f"BROAD README.md / REGISTRY.tsv not found in {SOURCE_DIR}")
    published = dict((name, digest) for digest, name in re.findall(r"^([0-9a-f]{64})\s+(\S+)$",
                                                                   readme.read_text(), flags=re.M))
    assert published == {name: e.sha256 for name, e in broad_io.BROAD_REGISTRY.items() if e.sha256}
    assert broad_io.BROAD_COMMIT in readme.read_text()
    rows = [line.split("\t") for line in registry.read_text().splitlines()[1:]]
    assert {name: download.RegistryEntry(None if sha == "-" else sha, blob) for name, sha, blob in rows} == (
        broad_io.BROAD_REGISTRY
    )


def test_present_trials_are_the_files_in_the_folder(tmp_path):
    assert broad_io.broad_trials(present_only=True, data_dir=tmp_path) == []
    for name in ("13_undisturbed_slow_translation_with_breaks_A", "02_undisturbed_slow_rotation_B"):
        (tmp_path / f"{name}.mat").write_bytes(b"")
    (tmp_path / "99_not_a_trial.mat").write_bytes(b"")
    (tmp_path / "trials.json").write_bytes(b"{}")
    assert broad_io.broad_trials(present_only=True, data_dir=tmp_path) == [
        "02_undisturbed_slow_rotation_B", "13_undisturbed_slow_translation_with_breaks_A"
    ]
    with pytest.raises(ValueError, match="present_only"):
        broad_io.broad_trials(present_only="yes")


@pytest.mark.skipif(not (SOURCE_DIR / "REGISTRY.tsv").exists(), reason=f"BROAD subset not found in {SOURCE_DIR}")
def test_shared_folder_holds_seventeen_trials():
    assert broad_io.broad_trials(present_only=True, data_dir=SOURCE_DIR) == SHARED_TRIALS


@pytest.mark.parametrize("spec", [2, np.int64(2), TRIAL, TRIAL_FILE])
def test_trial_given_by_name_or_number(spec):
    assert broad_io._broad_trial_name(spec) == TRIAL


@pytest.mark.parametrize("spec", [1, 13, 39, "01_undisturbed_slow_rotation_A", "39_disturbed_mixed.mat"])
def test_every_trial_of_the_dataset_is_known(spec, tmp_path):
    name = broad_io._broad_trial_name(spec)
    with pytest.raises(FileNotFoundError, match=re.escape(str(tmp_path / f"{name}.mat"))):
        broad_io.load_broad(spec, tmp_path, download=False)


@pytest.mark.parametrize("spec", [0, 40, 99, "02", "01_undisturbed_slow_rotation_B", True, 2.0, None])
def test_unknown_trial_lists_the_known_ones(spec):
    with pytest.raises(ValueError, match="known trials: .*02_undisturbed_slow_rotation_B.*39_disturbed_mixed"):
        broad_io.load_broad(spec, download=False)


def test_folder_resolution(tmp_path, monkeypatch):
    monkeypatch.delenv(broad_io.BROAD_DIR_ENV_VAR, raising=False)
    assert broad_io.broad_dir() == paths.ROOT / "data" / "raw" / "broad"
    monkeypatch.setenv(broad_io.BROAD_DIR_ENV_VAR, str(tmp_path / "env"))
    assert broad_io.broad_dir() == tmp_path / "env"
    assert broad_io.broad_dir(tmp_path / "arg") == tmp_path / "arg"
    assert not (tmp_path / "env").exists()  # resolving creates nothing


def test_missing_file_without_download(tmp_path):
    with pytest.raises(FileNotFoundError, match=re.escape(str(tmp_path / TRIAL_FILE))):
        broad_io.load_broad(TRIAL, tmp_path, download=False)


def test_unknown_file_name():
    with pytest.raises(ValueError, match="unknown BROAD file"):
        broad_io.broad_file("40_undisturbed_slow_rotation_A.mat")


@needs_files
def test_download_goes_to_the_pinned_url_and_is_verified(tmp_path, monkeypatch):
    folder = tmp_path / "new" / "broad"
    monkeypatch.setenv(broad_io.BROAD_DIR_ENV_VAR, str(folder))
    fake = CopyDownloader()
    loaded = broad_io.load_broad(2, downloader=fake)
    assert fake.urls == [
        f"https://raw.githubusercontent.com/dlaidig/broad/{broad_io.BROAD_COMMIT}/data_mat/{TRIAL_FILE}"
    ]
    assert (folder / TRIAL_FILE).read_bytes() == (SOURCE_DIR / TRIAL_FILE).read_bytes()
    assert loaded.name == TRIAL and loaded.n_samples == 53240
    broad_io.load_broad(2, downloader=fake)  # present now: no second download
    assert len(fake.urls) == 1
    info = json.loads(broad_io.broad_file("trials.json", downloader=fake).read_text(encoding="utf-8"))
    assert TRIAL in info["trials"] and len(fake.urls) == 2


@needs_files
@pytest.mark.parametrize("name", [TRIAL_FILE, "trials.json"])
def test_truncated_download_fails_and_leaves_nothing(tmp_path, name):
    fake = CopyDownloader(truncate=1000)
    with pytest.raises(ValueError, match=re.escape(name)) as info:
        broad_io.broad_file(name, tmp_path, downloader=fake)
    assert broad_io.BROAD_REGISTRY[name].sha256 in str(info.value)
    assert list(tmp_path.iterdir()) == []  # neither the bad file nor pooch's temporary copy


def test_failed_connection_is_an_os_error_with_a_hint(tmp_path):
    def offline(url, output_file, pooch):
        raise ConnectionError("network unreachable")

    with pytest.raises(OSError, match="WSNLIB_BROAD_DIR"):
        broad_io.broad_file("trials.json", tmp_path, downloader=offline)
    assert not (tmp_path / "trials.json").exists()
    with pytest.raises(OSError, match="WSNLIB_BROAD_DIR"):  # a folder made for the download goes too
        broad_io.broad_file("trials.json", tmp_path / "new" / "broad", downloader=offline)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("content", "blob_id"),
    [(b"", "e69de29bb2d1d6434b8b29ae775ad8c2e48c5391"), (b"hello\n", "ce013625030ba8dba906f756967f9e9ca394464a")],
)
def test_git_blob_id_is_what_git_computes(tmp_path, content, blob_id):
    path = tmp_path / "file"
    path.write_bytes(content)
    assert download.git_blob_sha1_of(path) == blob_id  # values of `git hash-object`


BLOB_FILE = "99_blob_only_test.mat"
BLOB_CONTENT = b"MATLAB-ish test content\n" * 50


@pytest.fixture
def blob_only_entry(monkeypatch, tmp_path):
    """A registry entry with a git blob id and no SHA-256, as for trials 13, 17, ... 39."""
    source = tmp_path / "source" / BLOB_FILE
    source.parent.mkdir()
    source.write_bytes(BLOB_CONTENT)
    entry = download.RegistryEntry(sha256=None, git_blob_sha1=download.git_blob_sha1_of(source))
    monkeypatch.setitem(broad_io.BROAD_REGISTRY, BLOB_FILE, entry)
    return entry


def test_blob_id_verifies_a_present_file(tmp_path, blob_only_entry):
    folder = tmp_path / "broad"
    folder.mkdir()
    path = folder / BLOB_FILE
    path.write_bytes(BLOB_CONTENT)
    assert broad_io.broad_file(BLOB_FILE, folder, download=False) == path
    path.write_bytes(BLOB_CONTENT[:-1] + b"!")  # same size, other content
    os.utime(path, ns=(path.stat().st_atime_ns, path.stat().st_mtime_ns + 10**9))
    with pytest.raises(ValueError, match="git blob id") as info:
        broad_io.broad_file(BLOB_FILE, folder, download=False)
    assert blob_only_entry.git_blob_sha1 in str(info.value) and download.git_blob_sha1_of(path) in str(info.value)
    assert str(path) in str(info.value)


def test_blob_id_verifies_a_download(tmp_path, blob_only_entry):
    def serve(content):
        def downloader(url, output_file, pooch):
            served.append(url)
            Path(output_file).write_bytes(content)
        return downloader

    served = []
    folder = tmp_path / "broad"
    with pytest.raises(ValueError, match="git blob id") as info:
        broad_io.broad_file(BLOB_FILE, folder, downloader=serve(BLOB_CONTENT[:100]))
    assert blob_only_entry.git_blob_sha1 in str(info.value)
    assert not folder.exists()  # neither the file, the partial download nor the folder made for them
    path = broad_io.broad_file(BLOB_FILE, folder, downloader=serve(BLOB_CONTENT))
    assert path == folder / BLOB_FILE and path.read_bytes() == BLOB_CONTENT
    assert list(folder.iterdir()) == [path]
    url = f"https://raw.githubusercontent.com/dlaidig/broad/{broad_io.BROAD_COMMIT}/data_mat/{BLOB_FILE}"
    assert served == [url, url]


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
        broad_io.load_broad(TRIAL, tmp_path, downloader=fake)
    message = str(info.value)
    assert str(path) in message and broad_io.BROAD_REGISTRY[TRIAL_FILE].sha256 in message
    assert broad_io.sha256_of(path) in message  # the actual hash too
    assert fake.urls == [] and path.read_bytes() == bytes(data)


@needs_files
def test_hash_is_cached_per_path_size_and_mtime(tmp_path, monkeypatch):
    path = tmp_path / "trials.json"
    shutil.copyfile(SOURCE_DIR / "trials.json", path)
    calls = []
    real = broad_io.sha256_of
    # patched where broad_file reads it
    monkeypatch.setattr(broad_io, "sha256_of", lambda p: calls.append(p) or real(p))
    broad_io.broad_file("trials.json", tmp_path, download=False)
    broad_io.broad_file("trials.json", tmp_path, download=False)
    assert len(calls) == 1
    # a change after verification is caught: same size, new content and mtime
    original = path.read_bytes()
    path.write_bytes(original.replace(b"slow", b"SLOW", 1))
    stat = path.stat()
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))
    with pytest.raises(ValueError, match="SHA-256"):
        broad_io.broad_file("trials.json", tmp_path, download=False)


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


@needs_files
def test_a_file_replaced_after_verification_is_checked_by_content(tmp_path):
    """Issue 23: same size and mtime, other bytes (a copy replaced in place): the remembered
    verification must not let a raw reader error through; the file is hashed again and named."""
    path = tmp_path / TRIAL_FILE
    shutil.copyfile(SOURCE_DIR / TRIAL_FILE, path)
    broad_io.load_broad(TRIAL, tmp_path, download=False)
    stat = path.stat()
    data = bytearray(path.read_bytes())
    data[len(data) // 2 : len(data) // 2 + 64] = bytes(64)  # inside the compressed signals
    path.write_bytes(bytes(data))
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    with pytest.raises(ValueError, match="SHA-256") as info:
        broad_io.load_broad(TRIAL, tmp_path, download=False)
    assert str(path) in str(info.value)
