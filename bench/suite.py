"""The benchmark classes of a run, in the order they run (``python -m avbench.bench`` runs them all).

Every speed claim is a ratio against a baseline timed in the same loop (:mod:`avbench.bench.harness`).
The classes live with what they measure:

* :mod:`avbench.bench.engine` -- the simulators and the Allan-variance family: :class:`Generation`,
  :class:`FlickerPreset`, :class:`AllanOverlapping`, :class:`Deviations`, :class:`AllanEngine`,
  :class:`AllanKernel`, :class:`StreamingMemory`;
* :mod:`avbench.bench.fits` -- the estimators' fits: :class:`EstimatorScaling`, :class:`FitCost`,
  :class:`OnlineKernels`, :class:`OnlineDefaults`, :class:`MleFit`, :class:`MleFitDrift`,
  :class:`WhittleFit`;
* :mod:`avbench.bench.recordings` -- a user's recording: :class:`ReadRecording`,
  :class:`EstimateMemory`, :class:`EstimateEndToEnd`; :mod:`avbench.bench.real_e2e` -- real and
  consumer-grade records end to end: :class:`EstimateRealRecords`;
* :mod:`avbench.bench.startup` -- whole processes: :class:`StartUp`, :class:`FirstCall`,
  :class:`LvStudy`, :class:`StudyJobs`.

>>> [c.__name__ for c in classes(quick=True)][:3]
['Generation', 'AllanOverlapping', 'Deviations']
>>> LvStudy in ALL and LvStudy not in classes(quick=True)
True
"""

from __future__ import annotations

from avbench.bench.engine import (
    AllanEngine,
    AllanKernel,
    AllanOverlapping,
    Deviations,
    FlickerPreset,
    Generation,
    StreamingMemory,
)
from avbench.bench.fits import (
    EstimatorScaling,
    FitCost,
    MleFit,
    MleFitDrift,
    OnlineDefaults,
    OnlineKernels,
    QuickOnlineKernels,
    WhittleFit,
)
from avbench.bench.real_e2e import EstimateRealRecords
from avbench.bench.recordings import EstimateEndToEnd, EstimateMemory, ReadRecording
from avbench.bench.report import loglog_slope
from avbench.bench.startup import FirstCall, LvStudy, QuickStartUp, StartUp, StudyJobs

__all__ = [
    "Generation",
    "AllanOverlapping",
    "Deviations",
    "AllanEngine",
    "EstimatorScaling",
    "OnlineKernels",
    "StreamingMemory",
    "LvStudy",
    "AllanKernel",
    "OnlineDefaults",
    "MleFit",
    "MleFitDrift",
    "WhittleFit",
    "FlickerPreset",
    "StartUp",
    "FirstCall",
    "ReadRecording",
    "EstimateMemory",
    "EstimateEndToEnd",
    "EstimateRealRecords",
    "FitCost",
    "StudyJobs",
    "ALL",
    "classes",
    "loglog_slope",
]

#: every benchmark of a full run
ALL = [Generation, AllanOverlapping, Deviations, AllanEngine, AllanKernel, EstimatorScaling, FitCost, OnlineKernels,
       OnlineDefaults, MleFit, MleFitDrift, WhittleFit, FlickerPreset, StreamingMemory, ReadRecording, EstimateMemory,
       EstimateEndToEnd, EstimateRealRecords, LvStudy, StudyJobs, StartUp, FirstCall]

#: the ``--quick`` run (tiny sizes, for CI): the quick variants of OnlineKernels and StartUp; no
#: EstimateEndToEnd, no LvStudy; EstimateRealRecords on a 2-minute consumer record
QUICK = [Generation, AllanOverlapping, Deviations, AllanEngine, AllanKernel, EstimatorScaling, FitCost,
         QuickOnlineKernels, OnlineDefaults, MleFit, MleFitDrift, WhittleFit, FlickerPreset, StreamingMemory,
         ReadRecording, EstimateMemory, EstimateRealRecords, QuickStartUp, FirstCall]


def classes(quick: bool) -> list:
    """The benchmark classes of a run (``quick``: the CI subset on tiny sizes)."""
    return list(QUICK if quick else ALL)
