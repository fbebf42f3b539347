"""Results kept per record: a function of a record (a 1-D array of samples) and of hashable options, asked
again for the same samples -- the spectral line test of each method fitted to one axis -- is computed once.

The key is the samples' bytes (a 128-bit BLAKE2b digest: ~10 ms for 10^7 bytes, against a periodogram's
median filter of ~0.1-1 s), their shape and the other arguments; the result is the one computed the first
time (the functions kept return immutable values). :data:`KEPT` results are kept, the least recently used
dropped first.
"""

from __future__ import annotations

import functools
import hashlib
import threading
from collections import OrderedDict

import numpy as np

__all__ = ["per_record", "KEPT"]

#: results kept per function
KEPT = 16
#: marks a key not kept (a kept result may be None)
_MISSING = object()


def per_record(f):
    """``f(x, *args, **kwargs)`` kept per (the bytes of ``x`` as float64, ``args``, ``kwargs``); computed
    afresh when an argument cannot be hashed."""
    kept: OrderedDict = OrderedDict()
    lock = threading.Lock()  # axes may be fitted in threads

    @functools.wraps(f)
    def wrapper(x, *args, **kwargs):
        a = np.ascontiguousarray(x, dtype=float)
        key = (hashlib.blake2b(a.view(np.uint8), digest_size=16).digest(), a.shape, args,
               tuple(sorted(kwargs.items())))
        try:
            with lock:
                out = kept.get(key, _MISSING)
                if out is not _MISSING:
                    kept.move_to_end(key)
                    return out
        except TypeError:  # an option that cannot be hashed
            return f(x, *args, **kwargs)
        out = f(x, *args, **kwargs)
        with lock:
            kept[key] = out
            while len(kept) > KEPT:
                kept.popitem(last=False)
        return out

    wrapper.kept = kept
    return wrapper
