"""File formats and dataset loaders: the io layer, which imports no simulator.

Every module here depends only on the core (numpy, pandas, scipy, :mod:`wsnlib.paths`,
:mod:`wsnlib.quaternion`, :mod:`wsnlib.frames`, :mod:`wsnlib.plausibility`, :mod:`wsnlib.testbed`
and the private helpers), never on :mod:`wsnlib.sim`, :mod:`wsnlib.orientation` or the studies;
the simulators import from here, not the other way round (``tests/test_layers.py`` checks it).

* :mod:`wsnlib.io.recording`: IMU recordings (:class:`~wsnlib.io.recording.Recording`) and their
  CSV + JSON format;
* :mod:`wsnlib.io.sidecar`: the sidecar writer/reader every CSV + JSON format here shares;
* :mod:`wsnlib.io.rss`: RSS recordings (paper 002), the long table's columns and checks, and
  the fingerprint vectors built from them;
* :mod:`wsnlib.io.accel`: accelerometer and Kinect sample tables (paper 002);
* :mod:`wsnlib.io.broad`: the BROAD benchmark trials (registry, verified download, loader);
* :mod:`wsnlib.io.pabr`: the PABR BLE RSSI dataset (registry, verified download, parsing,
  vectors);
* :mod:`wsnlib.io.vectors`: the one RSS vector type (:class:`~wsnlib.io.vectors.RssVectors`)
  and the one windowing function both RSS paths (``rss``, ``pabr``) build their vectors with;
* :mod:`wsnlib.io.download`: the verified download both dataset loaders share;
* :mod:`wsnlib.io.resample`: rate conversion of recordings whose rate ratio is a ratio of small
  integers (e.g. BROAD's 285.7 Hz to 50 Hz);
* :mod:`wsnlib.io.resample_timestamps`: resampling from time stamps (irregular, repeated, with gaps)
  to any rate;
* :mod:`wsnlib.io.alignment`: aligning an optical reference from another lab to an IMU (time lag,
  sensor-to-marker and lab-to-ENU rotations, from the sensors) and applying it;
* :mod:`wsnlib.io.health`: the health check to run on a recording before any study
  (:func:`~wsnlib.io.health.recording_health`: time base, repeated samples, reference vs
  gyroscope, magnetic field, units).
"""

from wsnlib.io import (
    accel,
    alignment,
    broad,
    download,
    health,
    pabr,
    recording,
    resample,
    resample_timestamps,
    rss,
    vectors,
)

__all__ = ["accel", "alignment", "broad", "download", "health", "pabr", "recording", "resample",
           "resample_timestamps", "rss", "vectors"]
