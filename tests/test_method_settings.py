"""Settings objects per method of estimate_orientation (wsnlib.orientation.method_settings):
the same result as the keywords, the keywords turned into the object in one place, any keyword
beside an object refused."""

import dataclasses

import numpy as np
import pytest
from _recordings import turning_recording

from wsnlib.orientation import (
    AdaptiveBetaSettings,
    DtExtensionSettings,
    GyroInterpolationSettings,
    HoldLastSettings,
    HybridSettings,
    KalmanMethodSettings,
    KalmanSettings,
    SingleFrameGate,
    estimate_orientation,
)
from wsnlib.orientation.method_settings import METHOD_KEYWORDS, UNSET, settings_from_arguments

FS = 50.0


@pytest.fixture(scope="module")
def data():
    gyr, acc, mag, _ = turning_recording(n=300, noise=0.02)
    rng = np.random.default_rng(4)
    received = rng.random((2, 300)) > 0.2
    received[:, :3] = True
    received[1, 100:130] = False
    return gyr, acc, mag, received


CASES = [
    (HoldLastSettings(beta=0.1), {"method": "hold_last", "beta": 0.1}),
    (HoldLastSettings(beta=0.1, gap="constant_rate", gap_time_constant=0.3),
     {"method": "hold_last", "beta": 0.1, "gap": "constant_rate", "gap_time_constant": 0.3}),
    (DtExtensionSettings(beta=0.05), {"method": "dt_extension", "beta": 0.05}),
    (GyroInterpolationSettings(beta=0.05), {"method": "gyro_interpolation", "beta": 0.05}),
    (AdaptiveBetaSettings(beta=0.05, beta_max=0.5, rho=1.0, tau=12.0, schedule="hold", hold_window=20),
     {"method": "adaptive_beta", "beta": 0.05, "beta_max": 0.5, "rho": 1.0, "tau": 12.0, "schedule": "hold",
      "hold_window": 20}),
    (HybridSettings(beta=0.041, rho=1.0, tau=48.0, blend="feedback"),
     {"method": "hybrid", "beta": 0.041, "rho": 1.0, "tau": 48.0, "blend": "feedback"}),
    (HybridSettings(beta=0.041, tau=np.array([[3.0], [24.0]]), single_frame_gate=SingleFrameGate(rate_limit=5.0),
                    gap="constant_rate"),
     {"method": "hybrid", "beta": 0.041, "tau": np.array([[3.0], [24.0]]),
      "single_frame_gate": SingleFrameGate(rate_limit=5.0), "gap": "constant_rate"}),
    (KalmanSettings(mag_noise=0.5), {"method": "kalman", "kalman_settings": KalmanSettings(mag_noise=0.5)}),
    (KalmanMethodSettings(settings=KalmanSettings(mag_noise=0.5), gap="hold"),
     {"method": "kalman", "kalman_settings": KalmanSettings(mag_noise=0.5), "gap": "hold"}),
    (KalmanMethodSettings(gap_time_constant=0.3), {"method": "kalman", "gap_time_constant": 0.3}),
]


@pytest.mark.parametrize("settings, keywords", CASES, ids=lambda c: type(c).__name__ if not isinstance(c, dict) else "")
def test_settings_object_equals_keywords(data, settings, keywords):
    gyr, acc, mag, received = data
    by_object = estimate_orientation(gyr, acc, mag, fs=FS, received=received, method=settings)
    by_keywords = estimate_orientation(gyr, acc, mag, fs=FS, received=received, **keywords)
    np.testing.assert_array_equal(by_object, by_keywords)


def test_settings_objects_are_frozen_and_replaceable(data):
    gyr, acc, mag, received = data
    hybrid = HybridSettings(beta=0.041)
    with pytest.raises(dataclasses.FrozenInstanceError):
        hybrid.rho = 3.0
    other = dataclasses.replace(hybrid, rho=0.5)
    assert other.rho == 0.5 and hybrid.rho == 2.0 and other.method == "hybrid"
    a = estimate_orientation(gyr, acc, mag, fs=FS, received=received, method=hybrid)
    b = estimate_orientation(gyr, acc, mag, fs=FS, received=received, method=other)
    assert np.abs(a - b).max() > 1e-6


@pytest.mark.parametrize(
    "settings, keywords, name",
    [
        (HybridSettings(beta=0.041), {"beta": 0.1}, "beta"),
        (HybridSettings(beta=0.041), {"rho": 3.0}, "rho"),
        (HybridSettings(beta=0.041), {"blend": "feedback"}, "blend"),
        (AdaptiveBetaSettings(beta=0.041), {"tau": np.array([1.0])}, "tau"),
        (HoldLastSettings(beta=0.041), {"gap": "constant_rate"}, "gap"),
        (KalmanSettings(), {"kalman_settings": KalmanSettings()}, "kalman_settings"),
        (HoldLastSettings(beta=0.041), {"kalman_settings": KalmanSettings()}, "kalman_settings"),
        (HoldLastSettings(), {}, "beta"),
        (HoldLastSettings(beta=-1.0), {}, "beta"),
        (HybridSettings(beta=0.1, rho=0.0), {}, "rho"),
        (DtExtensionSettings(beta=0.1, gap="constant_rate"), {}, "constant_rate"),
        ({"method": "hybrid"}, {}, "method"),
    ],
)
def test_conflicts_and_bad_values_raise(data, settings, keywords, name):
    gyr, acc, mag, received = data
    with pytest.raises(ValueError, match=name):
        estimate_orientation(gyr, acc, mag, fs=FS, received=received, method=settings, **keywords)


@pytest.mark.parametrize("keywords", [{"rho": 2.0}, {"schedule": "decay"}, {"hold_window": None},
                                      {"single_frame_gate": None}, {"beta": 0.041}])
def test_a_keyword_beside_a_settings_object_is_refused_even_at_its_default(data, keywords):
    gyr, acc, mag, received = data
    (name,) = keywords
    with pytest.raises(ValueError, match=f"{name} passed as keyword beside method=HybridSettings"):
        estimate_orientation(gyr, acc, mag, fs=FS, received=received, method=HybridSettings(beta=0.041), **keywords)


def test_gap_keyword_beside_a_bare_kalman_settings_points_to_kalman_method_settings(data):
    gyr, acc, mag, received = data
    with pytest.raises(ValueError, match="gap.*KalmanMethodSettings"):
        estimate_orientation(gyr, acc, mag, fs=FS, received=received, method=KalmanSettings(), gap="hold")


def _unset_except(**given):
    return {name: given.get(name, UNSET) for name in METHOD_KEYWORDS}


def test_keywords_become_the_settings_object_of_the_method():
    hybrid = settings_from_arguments("hybrid", _unset_except(beta=0.1, rho=3.0, blend="feedback", beta_max=0.5))
    assert type(hybrid) is HybridSettings
    assert (hybrid.beta, hybrid.rho, hybrid.tau, hybrid.blend) == (0.1, 3.0, 6.0, "feedback")  # beta_max: not hybrid's
    hold = settings_from_arguments("hold_last", _unset_except(beta=0.1, rho=3.0, schedule="hold"))
    assert type(hold) is HoldLastSettings and hold.beta == 0.1 and not hasattr(hold, "rho")
    kalman = settings_from_arguments("kalman", _unset_except(beta=0.1, kalman_settings=KalmanSettings(acc_noise=0.2),
                                                             gap="hold"))
    assert type(kalman) is KalmanMethodSettings
    assert kalman.settings == KalmanSettings(acc_noise=0.2) and kalman.gap == "hold"
    bare = settings_from_arguments(KalmanSettings(acc_noise=0.2), _unset_except())
    assert type(bare) is KalmanMethodSettings and bare.settings == KalmanSettings(acc_noise=0.2)
    same = HybridSettings(beta=0.1)
    assert settings_from_arguments(same, _unset_except()) is same


def test_unknown_keyword_name_is_refused():
    with pytest.raises(ValueError, match="not a method keyword: fs"):
        settings_from_arguments("hybrid", _unset_except() | {"fs": 50.0})
