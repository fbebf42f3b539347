"""Model choices made once per axis and shared by every method that fits it (:class:`AxisChoices`).

Several methods fitted to one axis of a record (``avbench estimate``'s defaults, ``gmwm_filtered`` and
``gmwm_despiked``) make the same model choices -- the shortest scale, a spectral line, a resonance, the bias
model -- whenever they are handed the same curve: ``gmwm_despiked`` on a record where no spike is found
matches the classical AV, the very values ``gmwm_filtered`` matches. A choice is a deterministic function
of what it is computed from, so a second method whose inputs are the first's, bit for bit, may take the
first's outcome instead of computing it again: the same numbers, without the refits.

What decides "the same inputs" is an :class:`AxisChoices` key the method builds from everything its choices
read (:func:`choice_key`: the samples' bytes, as a 128-bit BLAKE2b digest, the sampling interval, the AV
values matched, the settings that shape the choices and the code that makes them); a key that differs in
anything is another entry, so no outcome is ever shared where one of its inputs differs. Within a scope
opened by :func:`shared_choices` (``avbench.recordings.fit.fit_axis`` opens one per axis) a method asks
:func:`current` for the scope's :class:`AxisChoices` and :meth:`AxisChoices.outcome` for the outcome of its
key; outside any scope every method computes its own (a study's fits: one method per replicate and key).
Outcomes are handed out as deep copies: the method that receives one may change it.
"""

from __future__ import annotations

import contextlib
import contextvars
import copy
import hashlib
import threading
from collections.abc import Callable, Hashable

import numpy as np

__all__ = ["AxisChoices", "shared_choices", "current", "choice_key"]

_SCOPE: contextvars.ContextVar = contextvars.ContextVar("avbench_axis_choices", default=None)


def _digest(a) -> tuple:
    """(128-bit BLAKE2b digest of the bytes, shape, dtype) of an array, None kept as None."""
    if a is None:
        return (None,)
    a = np.ascontiguousarray(a)
    return (hashlib.blake2b(a.view(np.uint8), digest_size=16).digest(), a.shape, a.dtype.str)


def choice_key(rate, dt, arrays, settings: Hashable, code: Hashable) -> tuple:
    """The key of a method's choices on one record: the samples ``rate`` it sees (digest), the sampling
    interval ``dt``, the ``arrays`` its choices read (each by digest; None allowed), its ``settings`` (a
    hashable value of everything else that shapes them) and ``code`` (the functions that make them: a
    subclass that makes them otherwise has another key).

    >>> x = np.arange(8.0)
    >>> choice_key(x, 0.1, [x], ("a", 1), "f") == choice_key(x.copy(), 0.1, [x.copy()], ("a", 1), "f")
    True
    >>> choice_key(x, 0.1, [x], ("a", 1), "f") == choice_key(x + 1e-15 * x, 0.1, [x], ("a", 1), "f")
    False
    """
    return (_digest(np.asarray(rate, dtype=float)), float(dt), tuple(_digest(a) for a in arrays), settings, code)


class AxisChoices:
    """The outcomes of the model choices made on one axis, by key (:func:`choice_key`): the first method to
    ask for a key computes its outcome, every later one with the same key is handed a copy of it."""

    def __init__(self):
        self._kept: dict = {}
        self._lock = threading.Lock()
        self.computed = 0  # outcomes computed
        self.shared = 0  # outcomes handed to a later method

    def outcome(self, key: Hashable, compute: Callable[[], object]):
        """``compute()``'s value for ``key``: computed by the first caller, a deep copy of it for the others
        (the caller gets its own copy either way)."""
        with self._lock:
            kept = self._kept.get(key)
        if kept is not None:
            self.shared += 1
            return copy.deepcopy(kept[0])
        value = compute()
        with self._lock:
            self._kept[key] = (copy.deepcopy(value),)
            self.computed += 1
        return value


def current() -> AxisChoices | None:
    """The :class:`AxisChoices` of the innermost :func:`shared_choices` scope, None outside any."""
    return _SCOPE.get()


@contextlib.contextmanager
def shared_choices(choices: AxisChoices | None = None):
    """A scope whose methods share their choices on one axis (a new :class:`AxisChoices` unless given one);
    yields it.

    >>> with shared_choices() as kept:
    ...     a = kept.outcome("k", lambda: [1.0])
    ...     b = current().outcome("k", lambda: [2.0])
    >>> a, b, kept.computed, kept.shared, current() is None
    ([1.0], [1.0], 1, 1, True)
    """
    choices = AxisChoices() if choices is None else choices
    token = _SCOPE.set(choices)
    try:
        yield choices
    finally:
        _SCOPE.reset(token)
