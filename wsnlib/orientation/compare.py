"""Every estimator of the loss studies on the same data, in one call (notebook 05).

Our Madgwick-based loss-handling options (:func:`~wsnlib.orientation.loss_handling.estimate_orientation`),
single-frame TRIAD (held over gaps), and the peer filters Fusion and VQF
(:mod:`~wsnlib.orientation.peers`), plain and wrapped in paper 001's hybrid (eq. 4) with
output or feedback blending.  All see the same received samples.
"""

from __future__ import annotations

import numpy as np
from tqdm.auto import tqdm

from wsnlib.loss import hold_last
from wsnlib.orientation.loss_handling import blend_with_single_frame, estimate_orientation
from wsnlib.orientation.peers import fusion_ahrs, vqf_orientation
from wsnlib.orientation.triad import triad

#: Our options, in display order (``method=`` of estimate_orientation).
OUR_METHODS = ("hold_last", "dt_extension", "gyro_interpolation", "adaptive_beta", "hybrid")
#: Peer filters and their hybrid variants, in display order.
PEER_ESTIMATORS = ("Fusion", "Fusion + hybrid (output)", "Fusion + hybrid (feedback)",
                   "VQF", "VQF + hybrid (output)", "VQF + hybrid (feedback)")
SINGLE_FRAME = "single frame"


def run_estimators(gyr, acc, mag, *, fs: float, beta: float, received, hybrid: dict, peers: bool = True,
                   fusion_gain: float = 0.5, vqf_params: dict | None = None,
                   progress: bool = False) -> dict[str, np.ndarray]:
    """Run every estimator on one recording under a batch of loss masks.

    Parameters
    ----------
    gyr, acc, mag : array_like, shape (T, 3)
        rad/s, m/s², µT (body frame).
    fs : float
        Hz.
    beta : float
        Madgwick gain (rad/s) for our options.
    received : array_like of bool, shape (M, T)
        Loss masks (True = received); every estimator runs once per mask.
    hybrid : dict
        The hybrid setting: ``rho``, ``tau``, ``schedule``, ``blend`` and, for the ``"hold"``
        schedule, ``hold_window`` (e.g. :func:`wsnlib.tuning.read_recommendation`).  Used by
        our hybrid, by adaptive β (its β schedule uses the same μ) and by the peers' hybrids.
    peers : bool
        Also run Fusion and VQF.
    fusion_gain : float
        Fusion's gain (``gain=`` of :func:`~wsnlib.orientation.peers.fusion_ahrs`, default 0.5,
        Fusion's own), for Fusion and its hybrids.
    vqf_params : dict, optional
        VQF parameters (``params=`` of :func:`~wsnlib.orientation.peers.vqf_orientation`, e.g.
        ``{"tauAcc": 3.0}``; None = VQF's defaults), for VQF and its hybrids.
    progress : bool
        Show a progress bar over estimators.

    Returns
    -------
    dict[str, numpy.ndarray]
        Estimator name → ENU quaternions ``(M, T, 4)``, in the order of :data:`OUR_METHODS`,
        single frame, then :data:`PEER_ESTIMATORS`.
    """
    received = np.asarray(received)
    if received.ndim != 2:
        raise ValueError(f"received must have shape (M, T), got {received.shape}")
    shape = {"rho": float(hybrid["rho"]), "tau": float(hybrid["tau"]), "schedule": hybrid["schedule"]}
    if hybrid["schedule"] == "hold":
        shape["hold_window"] = int(hybrid["hold_window"])
    names = list(OUR_METHODS) + [SINGLE_FRAME] + (list(PEER_ESTIMATORS) if peers else [])
    results = {}
    for name in tqdm(names, desc="estimators", disable=not progress):
        if name in OUR_METHODS:
            options = {"method": name}
            if name in ("hybrid", "adaptive_beta"):
                options.update(shape)
            if name == "hybrid":
                options["blend"] = hybrid["blend"]
            results[name] = estimate_orientation(gyr, acc, mag, fs=fs, beta=beta, received=received, **options)
        elif name == SINGLE_FRAME:
            results[name] = hold_last(triad(acc, mag), received)
        else:
            library, _, variant = name.partition(" + hybrid ")
            mode = variant.strip("()") or None
            if mode == "output":  # an output stage on the plain filter's output: no second run
                results[name] = blend_with_single_frame(results[library], acc, mag, received, **shape)
                continue
            run = fusion_ahrs if library == "Fusion" else vqf_orientation
            extra = dict(shape) if mode else {}
            extra.update({"gain": fusion_gain} if library == "Fusion" else {"params": vqf_params})
            per_mask = [np.broadcast_to(x, received.shape + (3,)) for x in (gyr, acc, mag)]
            results[name] = run(*per_mask, fs=fs, received=received, hybrid=mode, **extra)
    return results
