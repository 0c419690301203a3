"""Parameters of the Kinect-like tracker's error model (:class:`KinectModel`) and the drawn
errors (:class:`KinectErrors`); the model, its sources and its assumptions are documented in
:mod:`wsnlib.sim.optical`, the simulation is :mod:`wsnlib.sim.kinect`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from wsnlib._validation import check_nonnegative, check_positive

#: Distance between the Kinect and the user in paper 002, Section 4.1 (m).
PAPER_CAMERA_DISTANCE_M = 3.0

#: Accepted values of ``relative_to`` in :func:`simulate_kinect`.
RELATIVE_TO = ("tracked_shoulder", "session_shoulder", "true_shoulder")


@dataclass(frozen=True)
class KinectModel:
    """Error parameters of a first-generation Kinect skeletal tracker (see the docstring of :mod:`wsnlib.sim.optical`).

    Parameters
    ----------
    frame_rate_hz : float
        Skeleton frame rate (Hz).  30 (Khoshelham & Oude Elberink 2012; paper 002).
    depth_noise_const_m, depth_noise_quad_m_per_m2, depth_noise_offset_m : float
        ``σ_depth(Z) = const + quad · (Z − offset)²`` (m): 0.0012 m, 0.0019 m/m², 0.4 m
        (Nguyen et al. 2012).
    lateral_noise_px : float
        Lateral noise (pixels); ``σ_lateral(Z) = lateral_noise_px · Z / focal_length_px`` (m).
        0.8 px (Nguyen et al. 2012).
    focal_length_px : float
        Depth-camera focal length (pixels).  585 (assumed).
    jitter_correlation_s : float
        Correlation time of the AR(1) jitter (s); 0 gives white jitter.  0.1 s (assumed).
    bias_std_m : float
        Standard deviation of the per-joint, per-session offset on each axis (m).  0.02
        (assumed).
    glitch_rate_hz : float
        Burst hazard of a joint in clear view (1/s).  0.02 (assumed).
    glitch_rate_occluded_hz : float
        Burst hazard at occlusion score 1 (1/s).  0.5 (assumed).
    glitch_mean_duration_s : float
        Mean burst duration (s); bursts last at least one frame.  0.3 (assumed).
    glitch_min_m, glitch_max_m : float
        Range of the burst error magnitude (m), uniform.  0.10–0.15 (paper 002, Section 5).
    """

    frame_rate_hz: float = 30.0
    depth_noise_const_m: float = 0.0012
    depth_noise_quad_m_per_m2: float = 0.0019
    depth_noise_offset_m: float = 0.4
    lateral_noise_px: float = 0.8
    focal_length_px: float = 585.0
    jitter_correlation_s: float = 0.1
    bias_std_m: float = 0.02
    glitch_rate_hz: float = 0.02
    glitch_rate_occluded_hz: float = 0.5
    glitch_mean_duration_s: float = 0.3
    glitch_min_m: float = 0.10
    glitch_max_m: float = 0.15

    def __post_init__(self):
        positive = ("frame_rate_hz", "focal_length_px", "glitch_mean_duration_s")
        for item in fields(self):
            value = getattr(self, item.name)
            if item.name in positive:
                number = check_positive(value, item.name)
            elif item.name == "depth_noise_offset_m":
                number = float(value)
                if not math.isfinite(number):
                    raise ValueError(f"depth_noise_offset_m must be finite, got {value!r}")
            else:
                number = check_nonnegative(value, item.name)
            object.__setattr__(self, item.name, number)
        if self.glitch_min_m > self.glitch_max_m:
            raise ValueError(
                f"glitch_min_m = {self.glitch_min_m} exceeds glitch_max_m = {self.glitch_max_m}"
            )

    @classmethod
    def noise_free(cls, frame_rate_hz: float = 30.0) -> KinectModel:
        """A model with every error component switched off (reports the truth at its frames)."""
        return cls(
            frame_rate_hz=frame_rate_hz,
            depth_noise_const_m=0.0,
            depth_noise_quad_m_per_m2=0.0,
            lateral_noise_px=0.0,
            bias_std_m=0.0,
            glitch_rate_hz=0.0,
            glitch_rate_occluded_hz=0.0,
        )

    @property
    def jitter_lag1_correlation(self) -> float:
        """Lag-1 (one frame) autocorrelation φ of the jitter."""
        if self.jitter_correlation_s == 0.0:
            return 0.0
        return math.exp(-1.0 / (self.frame_rate_hz * self.jitter_correlation_s))

    def depth_noise_std_m(self, depth_m) -> np.ndarray:
        """Jitter standard deviation along the camera axis at depth ``depth_m`` (m)."""
        depth = np.asarray(depth_m, dtype=float)
        return self.depth_noise_const_m + self.depth_noise_quad_m_per_m2 * (depth - self.depth_noise_offset_m) ** 2

    def lateral_noise_std_m(self, depth_m) -> np.ndarray:
        """Jitter standard deviation across the camera axis (each lateral axis) at ``depth_m`` (m)."""
        return self.lateral_noise_px * np.asarray(depth_m, dtype=float) / self.focal_length_px


@dataclass(frozen=True)
class KinectErrors:
    """The error components of one simulated Kinect session, before shoulder referencing.

    ``...`` are the batch dimensions of the input, ``K`` the number of Kinect frames, ``J`` the
    number of joints.  Reported positions are ``truth + bias + jitter + glitch``.

    Attributes
    ----------
    times : ndarray, shape (K,)
        Frame times (s), ``k / frame_rate_hz``.
    truth : ndarray, shape (..., K, J, 3)
        True joint positions at the frame times (m).
    bias : ndarray, shape (..., 1, J, 3)
        Per-joint session offsets (m).
    jitter : ndarray, shape (..., K, J, 3)
        Correlated anisotropic jitter (m).
    glitch : ndarray, shape (..., K, J, 3)
        Burst errors (m); zero outside bursts.
    glitch_active : ndarray of bool, shape (..., K, J)
        Frames inside a burst.
    glitch_start : ndarray of bool, shape (..., K, J)
        First frame of each burst.
    occlusion_score : ndarray, shape (..., K, J)
        The score ``s ∈ [0, 1]`` that set the burst hazard.
    """

    times: np.ndarray
    truth: np.ndarray
    bias: np.ndarray
    jitter: np.ndarray
    glitch: np.ndarray
    glitch_active: np.ndarray
    glitch_start: np.ndarray
    occlusion_score: np.ndarray

    @property
    def total(self) -> np.ndarray:
        """Absolute error ``bias + jitter + glitch``, shape (..., K, J, 3) (m)."""
        return self.bias + self.jitter + self.glitch
