"""From a user's recording to coefficients and a filter-ready yaml: the ``avbench estimate`` pipeline.

One module per step, in the order the data flows:

1. :mod:`~studies.recordings.readers` -- a file (CSV/text, NPY/NPZ, ROS 1/ROS 2 bag, PX4 ULog) becomes
   a :class:`~studies.recordings.readers.Recording`: named channels in the file's own units, their
   sensor (gyro/accel), the units the format defines (if any) and the time stamps (if any);
2. :mod:`~studies.recordings.timing` -- time stamps (or ``--fs``) become a
   :class:`~studies.recordings.timing.Timing`: the sample interval, its jitter, and the gaps, which
   split the record into gap-free runs;
3. :mod:`~studies.recordings.sensors` -- channels in SI units (through :mod:`noise_models.units`, the
   one units module), grouped by sensor and axis;
4. :mod:`~studies.recordings.fit` -- every estimator on every axis, gap-aware (clusters that straddle a
   gap are left out: :func:`estimators.allan.allan_variance_gaps`), failures kept as data, several
   recordings pooled and tested for agreement;
5. :mod:`~studies.recordings.report` -- the JSON payload with explicit flags, the screen tables, and
   :mod:`~studies.recordings.filter_yaml` (Kalibr ``imu.yaml``, imu_utils) and
   :mod:`~studies.recordings.figure` (Allan deviation with each fitted term).

``studies/estimate.py`` is the command that strings them together.
"""
