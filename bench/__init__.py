"""avbench performance benchmarks: ``python -m bench [--quick] [--out results/bench]``.

Modules: :mod:`avbench.bench.harness` (asv-style runner: medians of interleaved repeats, same-run
baselines), :mod:`avbench.bench.suite` (the benchmark classes), :mod:`avbench.bench.streaming` (peak memory of
the streaming path, in a child process), :mod:`avbench.bench.report` (README.md, results.json/csv,
scaling.png), and the authors' kernel-vs-reference throughput modules :mod:`avbench.bench.online_filters`
and :mod:`avbench.bench.arma_em`.
"""

if __name__ != "avbench.bench":  # the folder imported by its pre-0.2 name (from a source checkout)
    from avbench.renamed import moved as _moved

    raise ImportError(_moved(__name__))

