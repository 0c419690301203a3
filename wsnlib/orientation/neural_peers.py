"""A neural peer for inclination under packet loss: RIANN.

D. Weber, C. Gühmann, T. Seel, "RIANN — A Robust Neural Network Outperforms Attitude
Estimation Filters", AI 2(3) (2021) 444–463, doi:10.3390/ai2030028, through its package
``riann`` (0.2.0), whose wheel carries the trained network as an ONNX model run by
``onnxruntime``.  RIANN is a recurrent network (two GRU layers of 200 units) that reads, per
sample, the accelerometer (m/s²), the gyroscope (rad/s) and the time step Δt (s) since the
previous sample, and outputs the attitude.  It has no magnetometer input: its heading is
arbitrary (the start's, then drifting), only its inclination is meaningful.

Frames (established by static tests at several tilts, ``tests/test_neural_peers.py``)
--------------------------------------------------------------------------------------
RIANN's quaternion is ``[w, x, y, z]`` and rotates body vectors into an earth frame with z up,
exactly wsnlib's ENU up to the heading (its conjugate is off by the tilt).  No conversion.

Loss semantics
--------------
Only received samples reach the network, each with Δt = the *actual* time since the last
received sample ((index difference)/fs; the first received sample of a recording gets the
nominal 1/fs): unlike the filters of :mod:`wsnlib.orientation.peers`, whose libraries integrate
the nominal Δt, RIANN takes Δt as an input per sample, so a receiver that knows the sample
indices can tell it how much time went by.  On a lost sample the output is the previous
output; before the first received sample it is the output at that sample (as
:mod:`wsnlib.orientation.peers`).  The network starts from a zero hidden state at each batch
element's first received sample.

Each batch element's received samples go through the network in one ``onnxruntime`` call (the
model's batch dimension is fixed at 1, so batch elements loop in Python).  The network
computes in single precision; outputs are normalised again in double.
"""

from __future__ import annotations

import functools
import importlib.resources

import numpy as np

from wsnlib.orientation.peers import _hold, _prepare


@functools.cache
def _riann_session():
    """The ``onnxruntime`` session of the model in the ``riann`` wheel, loaded once per process.

    The model file is found through ``importlib.resources.files`` (``riann.RIANN()`` looks for it
    relative to the working directory when its own lookup fails, as it does in 0.2.0).  The session
    runs on one thread: a batch-1 recurrent network is a chain of small matrix-vector products, which
    a second thread does not make faster (the same wall time on two cores) while it spins for work,
    taking CPU time from whatever else runs (a notebook beside it, a study's other worker); the
    outputs are the same bits (``tests/test_neural_peers.py``).
    """
    try:  # imported here: onnxruntime is slow to import and only this peer needs it
        import onnxruntime
        import riann
    except ImportError as exc:
        raise ImportError("riann_orientation needs the packages 'riann' and 'onnxruntime' (pinned in "
                          "environment.lock; rebuild the venv with `make`)") from exc
    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = options.inter_op_num_threads = 1
    return onnxruntime.InferenceSession(str(importlib.resources.files(riann) / "riann.onnx"), options,
                                        providers=["CPUExecutionProvider"])


def _riann_one(session, gyr: np.ndarray, acc: np.ndarray, mask: np.ndarray, fs: float) -> np.ndarray:
    """``(T, 4)`` RIANN output on the received samples of one recording (other rows unset)."""
    index = np.flatnonzero(mask)
    dt = np.diff(index, prepend=index[0] - 1) / fs  # time since the last received sample
    features = np.concatenate((acc[index], gyr[index], dt[:, None]), axis=-1).astype(np.float32)
    hidden = np.zeros(tuple(session.get_inputs()[1].shape), dtype=np.float32)
    quat = session.run(None, {"input": features[None], "h0": hidden})[0][0].astype(float)
    out = np.empty((mask.shape[-1], 4))
    out[index] = quat / np.linalg.norm(quat, axis=-1, keepdims=True)
    return out


def riann_orientation(gyr, acc, *, fs: float, received=None) -> np.ndarray:
    """RIANN's attitude (Weber, Gühmann & Seel 2021) over whole recordings, with packet loss, batched.

    Parameters
    ----------
    gyr, acc : array_like, shape (..., T, 3)
        Angular rate (rad/s) and specific force (m/s², +g up at rest) in the body frame, the
        units RIANN was trained on.
    fs : float
        Sampling rate (Hz), > 0: sample k is at k/fs s, and each received sample is fed with
        Δt = the time since the previous received one (:mod:`wsnlib.orientation.neural_peers`).
    received : array_like of bool, shape (..., T), optional
        True = received; lost samples are never read (they may hold NaN).  ``None``: all.

    Returns
    -------
    numpy.ndarray, shape (..., T, 4)
        Unit quaternions ``[w, x, y, z]``, body → earth, earth z up; the heading is arbitrary
        (no magnetometer): compare inclinations only.  ``...`` is the broadcast of the leading
        dimensions of the signals and ``received``.  Lost samples hold the previous output;
        samples before the first received one hold the output at it.

    Raises
    ------
    ValueError
        Naming the argument: wrong shapes, mismatched T, leading dimensions that do not
        broadcast, a non-boolean ``received``, NaN/inf or a zero ``acc`` vector in a received
        sample, ``fs`` <= 0, or a batch element with no received sample.
    ImportError
        If ``riann`` or ``onnxruntime`` is not installed.
    """
    fs, signals, mask, batch = _prepare(gyr, acc, None, fs, received)
    session = _riann_session()
    out = np.empty(batch + (mask.shape[-1], 4))
    for idx in np.ndindex(*batch):
        one = _riann_one(session, signals["gyr"][idx], signals["acc"][idx], mask[idx], fs)
        out[idx] = _hold(one, mask[idx])
    return out
