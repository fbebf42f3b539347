"""avbench performance benchmarks: ``python -m bench [--quick] [--out results/bench]``.

Modules: :mod:`bench.harness` (asv-style runner: medians of interleaved repeats, same-run
baselines), :mod:`bench.suite` (the benchmark classes), :mod:`bench.streaming` (peak memory of
the streaming path, in a child process), :mod:`bench.report` (README.md, results.json/csv,
scaling.png), and the authors' kernel-vs-reference throughput modules :mod:`bench.online_filters`
and :mod:`bench.arma_em`.
"""
