"""avbench performance benchmarks: ``python -m avbench.bench [--quick] [--out results/bench]``.

Modules: :mod:`avbench.bench.harness` (asv-style runner: medians of interleaved repeats, same-run
baselines), :mod:`avbench.bench.suite` (the classes of a run), the benchmark classes by what they
measure -- :mod:`avbench.bench.engine` (simulators, Allan variances), :mod:`avbench.bench.fits` (the
estimators), :mod:`avbench.bench.recordings` (reading a recording, ``avbench estimate``),
:mod:`avbench.bench.real_e2e` (``avbench estimate`` on real and consumer-grade records, with its records in
:mod:`avbench.bench.real_records`) and
:mod:`avbench.bench.startup` (start-up, first calls, the lv2015 study) -- with their helpers
:mod:`avbench.bench.streaming` (peak memory of the streaming path, in a child process),
:mod:`avbench.bench.estimate_e2e` and the kernel-vs-reference throughput modules
:mod:`avbench.bench.online_filters` and :mod:`avbench.bench.arma_em`; :mod:`avbench.bench.report`
writes README.md, results.json/csv and scaling.png.
"""

if __name__ != "avbench.bench":  # the folder imported by its pre-0.2 name (from a source checkout)
    from avbench.renamed import moved as _moved

    raise ImportError(_moved(__name__))

