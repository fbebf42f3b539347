"""What a user waits for before any work: start-up, the first call of a compiled filter, parallel studies.

Every figure is measured in fresh child processes (the runner's own imports and caches never count):

* :func:`help_times` -- wall time of ``avbench --help`` and of every subcommand's help, against the
  bare interpreter (``python -c pass``) timed in the same loop;
* :func:`import_cpu` -- CPU seconds of ``from avbench import estimators, noise_models`` (``time.process_time``
  around the import in a fresh interpreter);
* :func:`first_call` -- for one estimator, with an empty numba cache folder (``NUMBA_CACHE_DIR``, so
  the user's own cache is neither used nor touched): a first process compiles (the first-ever cost),
  a second process loads the kernels from that cache; each fits the same record twice, and the
  first-call cost is the first fit minus the second (what the fit imports lazily included; the
  import of the estimator's own module is timed apart);
* :func:`study_walls` -- ``avbench run studies/lv2015.toml`` with ``--jobs 1`` and ``--jobs 2``,
  alternated, each into a fresh output folder; :func:`replicate_profile` -- where a replicate's time goes;
* :func:`jobs_costs` -- a study of two blocks with ``--jobs 64`` against ``--jobs`` the cores, alternated
  (wall and CPU seconds): the worker count is capped at the cores and the blocks.

The benchmark classes that run them: :class:`StartUp` (``avbench --help`` and every subcommand's help
against the bare interpreter, CPU time of ``from avbench import estimators, noise_models``),
:class:`FirstCall` (each filter's first-ever compile and second-process first-call cost) and
:class:`LvStudy` (lv2015 with ``--jobs 1`` and ``--jobs 2`` from fresh processes, alternated; full
run only) and :class:`StudyJobs` (:func:`jobs_costs`; full run only).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from avbench.bench.fits import ESTIMATOR_SETTINGS

__all__ = ["help_times", "import_cpu", "first_call", "study_walls", "jobs_costs", "replicate_profile", "HELP_COMMANDS",
           "FIRST_CALL_ESTIMATORS", "StartUp", "QuickStartUp", "FirstCall", "LvStudy", "StudyJobs"]

ROOT = Path(__file__).resolve().parents[1]
#: the help screens timed: the program's and every subcommand's
HELP_COMMANDS = [[], ["presets"], ["estimators"], ["studies"], ["simulate"], ["run"], ["table"], ["estimate"],
                 ["check-estimator"], ["bench"]]
#: estimators whose first call is measured (the compiled filters and the optimiser-based fits)
FIRST_CALL_ESTIMATORS = ["shakf", "shakf_multitau", "nekf", "nekf_multitau", "arma_em", "mle", "gmwm", "wls"]


def _env(**extra) -> dict:
    return {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""),
            "MPLBACKEND": "Agg", **extra}


def _avbench() -> list[str]:
    """The installed ``avbench`` script beside this interpreter, else ``python -m avbench.cli``."""
    script = Path(sys.executable).with_name("avbench")
    return [str(script)] if script.is_file() else [sys.executable, "-m", "avbench.cli"]


def _wall(cmd, env=None) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT, env=env or _env())
    return time.perf_counter() - t0


def help_times(repeats: int = 5) -> dict:
    """Median wall seconds of each help screen and of the bare interpreter (same loop, alternated)."""
    cmds = {"python -c pass": [sys.executable, "-c", "pass"]}
    cmds.update({" ".join(["avbench", *sub, "--help"]): _avbench() + [*sub, "--help"] for sub in HELP_COMMANDS})
    times: dict[str, list[float]] = {k: [] for k in cmds}
    for _ in range(repeats):
        for k, c in cmds.items():
            times[k].append(_wall(c))
    med = {k: float(np.median(v)) for k, v in times.items()}
    helps = {k: v for k, v in med.items() if k.startswith("avbench")}
    worst = max(helps, key=helps.get)
    return {"help_max_s": helps[worst], "help_worst": worst, "help_median_s": float(np.median(list(helps.values()))),
            "interpreter_s": med["python -c pass"], "help_s": helps, "repeats": repeats}


def import_cpu(repeats: int = 5, modules: str = "estimators, noise_models") -> dict:
    """CPU seconds (median) of ``from avbench import <modules>`` in a fresh interpreter, and its wall time."""
    code = (f"import time; c = time.process_time(); w = time.perf_counter(); from avbench import {modules}; "
            "print(time.process_time() - c, time.perf_counter() - w)")
    cpu, wall = [], []
    for _ in range(repeats):
        out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True, cwd=ROOT,
                             env=_env()).stdout.split()
        cpu.append(float(out[0]))
        wall.append(float(out[1]))
    return {"import_cpu_s": float(np.median(cpu)), "import_wall_s": float(np.median(wall)), "repeats": repeats}


_FIRST_CALL_CHILD = r"""
import json, sys, time, warnings
import numpy as np
t0 = time.perf_counter()
from avbench import estimators
from avbench.noise_models import AngleRandomWalk, GaussMarkov, Gyro, RateRandomWalk
name, settings = sys.argv[1], json.loads(sys.argv[2])
g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=8.7e-4), GaussMarkov(sigma=1e-4, tc=50.0), RateRandomWalk(K=2e-6)])
truth = {c: float(g.coefficients[c]) for c in "NBK"}
settings = {k: (truth if v == "truth" else v) for k, v in settings.items()}
rate = g.simulate(20_000, np.random.default_rng(0))
t1 = time.perf_counter()
estimators.estimator_class(name)  # the estimator's module (and what it imports at its top)
t2 = time.perf_counter()
fits = []
for _ in range(4):  # the first fit, then three: their median is what a fit costs once the kernels are in
    est = estimators.get(name, **settings)
    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with np.errstate(all="ignore"):
            est.fit(rate, g.dt)
    fits.append(time.perf_counter() - t)
print(json.dumps({"setup_s": t1 - t0, "module_s": t2 - t1, "first_fit_s": fits[0],
                  "second_fit_s": float(np.median(fits[1:]))}))
"""


#: later processes whose first-call cost is measured (the median is reported)
WARM_PROCESSES = 3


def first_call(estimator: str, settings: dict) -> dict:
    """First-ever compile cost and the second process's first-call cost of one estimator (seconds).

    ``settings`` may hold the string "truth" for ``x0`` (the record's true N, B, K).
    """
    cache = tempfile.mkdtemp(prefix="avbench_numba_cache_")
    try:
        runs = []
        # 1: empty cache (compiles and writes it); then WARM_PROCESSES later processes (load it): a first call's
        # extra cost is the difference of two fit times, so for an estimator whose fit takes seconds (mle) one
        # process's figure moves by tenths of a second between runs; the median of three does not
        for _ in range(1 + WARM_PROCESSES):
            out = subprocess.run([sys.executable, "-c", _FIRST_CALL_CHILD, estimator, json.dumps(settings)],
                                 check=True, capture_output=True, text=True, cwd=ROOT,
                                 env=_env(NUMBA_CACHE_DIR=cache), timeout=900)
            runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    cold, warms = runs[0], runs[1:]
    extra = [w["first_fit_s"] - w["second_fit_s"] for w in warms]
    warm = warms[int(np.argsort(extra)[len(extra) // 2])]  # the process with the median extra cost
    return {
        "first_ever_s": cold["first_fit_s"] - cold["second_fit_s"],
        "second_process_s": float(np.median(extra)),
        "warm_processes": len(warms),
        "fit_s": min(cold["second_fit_s"], warm["second_fit_s"]),
        "second_process_first_fit_s": warm["first_fit_s"],
        "second_process_setup_s": warm["setup_s"],
        "second_process_module_s": warm["module_s"],
    }


def study_walls(study: str = "lv2015", rounds: int = 2, warm: bool = True) -> dict:
    """Wall seconds of ``avbench run <study> --jobs 1`` and ``--jobs 2`` (alternated, medians).

    ``warm``: first an untimed one-replicate run (kernels in numba's disk cache, files in the OS cache).
    """
    config = ROOT / "studies" / f"{study}.toml"

    def run(jobs, *extra):
        out = Path(tempfile.mkdtemp(prefix="avbench_bench_study_"))
        try:
            return _wall(_avbench() + ["run", str(config), "--jobs", str(jobs), "--out", str(out), "--no-progress",
                                       *extra])
        finally:
            shutil.rmtree(out, ignore_errors=True)

    if warm:
        run(1, "--replicates", "1")
    walls: dict[int, list[float]] = {1: [], 2: []}
    for r in range(rounds):
        for jobs in ((2, 1) if r % 2 else (1, 2)):
            walls[jobs].append(run(jobs))
    j1, j2 = float(np.median(walls[1])), float(np.median(walls[2]))
    return {"wall_jobs1_s": j1, "wall_jobs2_s": j2, "speedup": j1 / j2, "rounds": rounds,
            "loadavg_after": list(os.getloadavg())}


#: the study of :func:`jobs_costs`: two gyros, one block of two replicates each (two blocks of work)
JOBS_STUDY = """[study]
name = "jobs"
seed = 7
replicates = 2
n_samples = 3000
block_size = 2

[[gyros]]
name = "g1"
dt = 0.1
terms = [{type = "AngleRandomWalk", N = [0.5, "deg/sqrt(h)"]}, {type = "BiasInstability", B = [10.0, "deg/h"], tau_max = 600.0}]

[[gyros]]
name = "g2"
dt = 0.05
terms = [{type = "AngleRandomWalk", N = [0.2, "deg/sqrt(h)"]}, {type = "RateRandomWalk", K = [50.0, "deg/h^1.5"]}]

[[estimators]]
name = "wls"
settings = { terms = "NBK", taus = "all" }
"""


def jobs_costs(many: int = 64, rounds: int = 2) -> dict:
    """Wall and CPU seconds (the command's process and its workers) of ``avbench run`` on a study of two
    blocks with ``--jobs many`` and with ``--jobs`` the cores, alternated, medians; ``ratio``: the
    former's wall over the latter's (the worker count is capped at the cores and the blocks, so ~1)."""
    import resource

    folder = Path(tempfile.mkdtemp(prefix="avbench_bench_jobs_"))
    config = folder / "jobs.toml"
    config.write_text(JOBS_STUDY)
    cores = os.cpu_count() or 1

    def run(jobs):
        out = folder / f"out{jobs}"
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        wall = _wall(_avbench() + ["run", str(config), "--jobs", str(jobs), "--out", str(out), "--no-progress"])
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        shutil.rmtree(out, ignore_errors=True)
        return wall, (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)

    try:
        got: dict[int, list[tuple[float, float]]] = {many: [], cores: []}
        for r in range(rounds):
            for jobs in ((cores, many) if r % 2 else (many, cores)):
                got[jobs].append(run(jobs))
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    med = {j: np.median(np.array(v), axis=0) for j, v in got.items()}
    return {f"wall_jobs{many}_s": float(med[many][0]), f"cpu_jobs{many}_s": float(med[many][1]),
            f"wall_jobs{cores}_s": float(med[cores][0]), f"cpu_jobs{cores}_s": float(med[cores][1]),
            "ratio": float(med[many][0] / med[cores][0]), "cores": cores, "rounds": rounds}


def _time_report(out: Path, study: str) -> float:
    """Seconds to rewrite the finished study's tables and figures (avbench.studies.report.write_report)."""
    from avbench.studies.config import load_config
    from avbench.studies.report import read_tidy, write_report

    cfg = load_config(ROOT / "studies" / f"{study}.toml")
    tidy = read_tidy(out)
    (out / "_bench_report").mkdir()
    t0 = time.perf_counter()
    write_report(cfg, tidy, out / "_bench_report")
    return time.perf_counter() - t0


def replicate_profile(study: str = "lv2015") -> dict:
    """Where the time goes: imports (fresh process), config, one replicate's simulation and fits."""
    code = "import time; t=time.perf_counter(); import avbench.studies.runner, avbench.studies.report; print(time.perf_counter()-t)"
    imp = float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                               check=True).stdout.strip())
    from avbench.estimators.allan.variance import memoize_allan
    from avbench.studies.config import load_config
    from avbench.studies.runner import _fit_one, replicate_rng

    t0 = time.perf_counter()
    cfg = load_config(ROOT / "studies" / f"{study}.toml")
    t_cfg = time.perf_counter() - t0
    sims, fits = [], []
    for r in range(4):
        g = cfg.gyros[r % len(cfg.gyros)]
        t0 = time.perf_counter()
        rate = g.gyro.simulate(g.n_samples, replicate_rng(cfg.seed, r % len(cfg.gyros), 100 + r))
        t1 = time.perf_counter()
        with memoize_allan():
            for e in cfg.estimators:
                _fit_one(e, g, rate, g.gyro.dt)
        sims.append(t1 - t0)
        fits.append(time.perf_counter() - t1)
    return {"imports_s": imp, "config_s": t_cfg, "replicate_simulate_s": float(np.median(sims[1:])),
            "replicate_fits_s": float(np.median(fits[1:])), "replicates": cfg.replicates * len(cfg.gyros)}


class StartUp:
    """``avbench --help`` (and every subcommand's) vs the bare interpreter; CPU of the package imports."""

    params = [["fresh process"]]
    param_names = ["process"]
    help_repeats = 5

    def setup(self, process):
        pass

    def track_help(self, process):
        return help_times(self.help_repeats)

    def track_import(self, process):
        return import_cpu(self.help_repeats)


class QuickStartUp(StartUp):
    """:class:`StartUp` with one repeat (``--quick``)."""

    help_repeats = 1


class FirstCall:
    """Each estimator's first fit: first-ever (empty numba cache) and in a second process."""

    params = [FIRST_CALL_ESTIMATORS]
    quick_params = [["wls"]]
    param_names = ["estimator"]

    def setup(self, estimator):
        from avbench import estimators

        if estimator not in estimators.names():
            raise NotImplementedError
        self.settings = dict(ESTIMATOR_SETTINGS.get(estimator, {}))
        if "terms" in estimators.estimator_class(estimator)._param_names():
            self.settings["terms"] = "NBK"

    def track_first_call(self, estimator):
        return first_call(estimator, self.settings)


class LvStudy:
    """``avbench run studies/lv2015.toml --jobs 2`` from a fresh process, and a replicate's profile."""

    params = [["lv2015"]]
    quick_params = [[]]
    param_names = ["study"]

    def setup(self, study):
        pass

    def track_wall(self, study):
        out = Path(tempfile.mkdtemp(prefix="avbench_bench_"))
        try:  # untimed first run: warms numba's disk cache and the OS file cache, gives a tidy table
            subprocess.run([sys.executable, "-m", "avbench.cli", "run", str(ROOT / "studies" / f"{study}.toml"),
                            "--jobs", "2", "--out", str(out), "--no-progress"],
                           check=True, capture_output=True, cwd=ROOT, timeout=1800)
            t_report = _time_report(out, study)
        finally:
            shutil.rmtree(out, ignore_errors=True)
        walls = study_walls(study, rounds=2, warm=False)
        return {"wall_s": walls["wall_jobs2_s"], "report_s": t_report, **walls, **replicate_profile(study)}


class StudyJobs:
    """``avbench run`` of a two-block study with ``--jobs 64`` against ``--jobs`` the cores (same loop)."""

    params = [[64]]
    quick_params = [[8]]
    param_names = ["jobs"]
    rounds = 2

    def setup(self, jobs):
        pass

    def track_cost(self, jobs):
        return jobs_costs(jobs, self.rounds)
