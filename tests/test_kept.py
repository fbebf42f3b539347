"""Results kept per record (``estimators.selection._kept.per_record``): the same samples and options give the
result computed the first time; anything else is computed afresh."""

import numpy as np

from avbench.estimators.selection._kept import KEPT, per_record


def test_per_record_computes_once_per_samples_and_options_and_keeps_none():
    calls = []

    @per_record
    def f(x, k=0):
        calls.append(k)
        return None if k == 1 else float(np.sum(x)) + (len(k) if isinstance(k, list) else k)

    x = np.arange(10.0)
    assert f(x) == f(x.copy()) == 45.0 and len(calls) == 1
    assert f(x, k=1) is None and f(x, k=1) is None and len(calls) == 2
    assert f(x + 1.0) == 55.0 and len(calls) == 3
    assert f(x, k=[1]) == 46.0 and f(x, k=[1]) == 46.0 and len(calls) == 5  # not hashable: not kept


def test_per_record_keeps_the_most_recent():
    @per_record
    def f(x):
        return float(x[0])

    for i in range(KEPT + 5):
        f(np.array([float(i)]))
    assert len(f.kept) == KEPT
