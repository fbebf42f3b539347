"""From a user's recording to coefficients and a filter-ready yaml: the ``avbench estimate`` pipeline.

One module per step, in the order the data flows:

1. :mod:`~avbench.recordings.readers` -- a file (CSV/text incl. EuRoC/TUM-VI, NPY/NPZ, MATLAB .mat, ROS 1/ROS 2
   bag, PX4 ULog) becomes a :class:`~avbench.recordings.readers.Recording`: named channels in the file's
   own units, their sensor (gyro/accel), the units the format defines (if any) and the time stamps (if
   any). One module per kind of file: :mod:`~avbench.recordings.text_tables`,
   :mod:`~avbench.recordings.arrays` (npy, npz, mat), :mod:`~avbench.recordings.bags` (ROS bags, PX4 ULog),
   sharing :mod:`~avbench.recordings.channels`;
2. :mod:`~avbench.recordings.timing` -- time stamps (their unit by :mod:`~avbench.recordings.time_units`),
   the file's stated rate or ``--fs`` become a :class:`~avbench.recordings.timing.Timing`: the sample
   interval, its jitter, and the gaps, which split the record into gap-free runs;
3. :mod:`~avbench.recordings.sensors` -- channels in SI units (through :mod:`avbench.noise_models.units`, the
   one units module), grouped by sensor and axis;
3b. :mod:`~avbench.recordings.static` -- does the record look like a sensor at rest (said before the fits);
4. :mod:`~avbench.recordings.fit` -- every estimator on every axis, gap-aware (clusters that straddle a
   gap are left out: :func:`avbench.estimators.allan.variance.allan_variance_gaps`), failures kept as data, several
   recordings pooled and tested for agreement;
5. :mod:`~avbench.recordings.report` -- the JSON payload with explicit flags, the screen tables, and
   :mod:`~avbench.recordings.filter_yaml` (Kalibr ``imu.yaml``, imu_utils) and
   :mod:`~avbench.recordings.figure` (Allan deviation with each fitted term); the files are planned
   before the fits and written as one set (:mod:`~avbench.recordings.plan`).

Steps 1-3 are one call, :func:`load_recording` (:mod:`~avbench.recordings.load`), with the reader options of
the command line as keywords. :func:`estimate_file` (:mod:`~avbench.recordings.estimate`) reads a recording
and fits every method to every axis: ``{sensor: {axis: {method: MethodFit}}}``. The command
``avbench estimate`` (:mod:`~avbench.recordings.estimate`) strings every step together, with the outputs;
``avbench deviations`` reads as it does.
"""

__all__ = ["load_recording", "estimate_file"]


def __getattr__(name):
    # imported on first use: importing one step's module (avbench.recordings.files, ...) stays light
    if name == "load_recording":
        from avbench.recordings.load import load_recording

        return load_recording
    if name == "estimate_file":
        from avbench.recordings.estimate import estimate_file

        return estimate_file
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *__all__])
