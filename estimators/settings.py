"""Declared settings: every estimator states what each of its settings accepts, and one function checks them.

An estimator class declares ``parameter_constraints``, a mapping from each ``__init__`` setting to a
list of constraints; a value is accepted when it satisfies any of them (the shape of scikit-learn's
``_parameter_constraints``), and ``setting_relations``, the :class:`Relation` s between settings (a
filter time constant that needs a filter term, say). :func:`validate_settings` checks a set of values
against both and raises a ``ValueError`` naming the setting, what it accepts and what it was given --
before any data is seen. It is the one check: ``estimators.get``, ``Estimator.fit``, a study config
and ``avbench estimate --set`` call it, so a setting is refused by each with the same message; a
setting the class does not declare is refused naming the declared ones (a class that declares nothing,
a plugin say, accepts the settings of its ``__init__`` unchecked).

>>> from avbench.estimators import Estimator
>>> from avbench.estimators.settings import Interval, Options, validate_settings
>>> class Demo(Estimator):
...     name = "demo"
...     parameter_constraints = {"n_starts": [Interval(int, 1, None)], "weighting": [Options("model", "diagonal")]}
...     def __init__(self, *, n_starts=4, weighting="model"):
...         self.n_starts, self.weighting = n_starts, weighting
>>> validate_settings(Demo, {"n_starts": 3, "weighting": "model"})
>>> validate_settings(Demo, {"colour": "red"})
Traceback (most recent call last):
...
ValueError: estimator 'demo': unknown setting(s) colour; accepted: n_starts, weighting
>>> validate_settings(Demo, {"n_starts": 0, "weighting": "model"})
Traceback (most recent call last):
...
ValueError: estimator 'demo': n_starts=0: expected an integer >= 1
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable as _Callable
from collections.abc import Mapping

import numpy as np

__all__ = ["Constraint", "Interval", "Options", "Boolean", "NoneValue", "Instance", "Terms", "Taus",
           "Coefficients", "Check", "Relation", "validate_settings", "undeclared"]


class Constraint:
    """One kind of value a setting accepts: ``accepts(value)`` and a short description for messages."""

    def accepts(self, value) -> bool:  # pragma: no cover - abstract
        raise NotImplementedError

    def describe(self) -> str:  # pragma: no cover - abstract
        raise NotImplementedError

    def explain(self, value) -> str | None:
        """Why ``value`` is refused, where that says more than :meth:`describe` (None: it does not)."""
        return None

    def __repr__(self) -> str:
        return f"<{self.describe()}>"


def _is_bool(v) -> bool:
    return isinstance(v, bool | np.bool_)


class Interval(Constraint):
    """A real (``float``) or integer (``int``) number in ``[low, high]`` (None: unbounded); ``closed``
    says which ends belong to it ("both", "left", "right", "neither"). Booleans are not numbers here,
    and a real must be finite."""

    def __init__(self, kind, low=None, high=None, closed="both"):
        if kind not in (int, float):
            raise ValueError(f"Interval kind: expected int or float, got {kind!r}")
        if closed not in ("both", "left", "right", "neither"):
            raise ValueError(f"Interval closed: expected both, left, right or neither, got {closed!r}")
        self.kind, self.low, self.high, self.closed = kind, low, high, closed

    def accepts(self, value) -> bool:
        if _is_bool(value):
            return False
        if self.kind is int:
            if not isinstance(value, numbers.Integral):
                return False
        elif not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
            return False
        if self.low is not None:
            if value < self.low or (value == self.low and self.closed in ("right", "neither")):
                return False
        if self.high is not None:
            if value > self.high or (value == self.high and self.closed in ("left", "neither")):
                return False
        return True

    def describe(self) -> str:
        what = "an integer" if self.kind is int else "a finite number"
        lo_op = ">=" if self.closed in ("both", "left") else ">"
        hi_op = "<=" if self.closed in ("both", "right") else "<"
        parts = ([f"{lo_op} {self.low:g}"] if self.low is not None else []) + \
                ([f"{hi_op} {self.high:g}"] if self.high is not None else [])
        return f"{what} {' and '.join(parts)}".rstrip()


class Options(Constraint):
    """One of a fixed set of values (strings, usually); compared with ``==`` and of the same type, so
    that ``1`` does not pass for ``True`` nor ``"1"`` for ``1``."""

    def __init__(self, *values):
        if not values:
            raise ValueError("Options: expected at least one value")
        self.values = values

    def accepts(self, value) -> bool:
        return any(type(value) is type(v) and value == v for v in self.values)

    def describe(self) -> str:
        return "one of " + ", ".join(repr(v) for v in self.values)


class Boolean(Constraint):
    """True or False (a string such as "yes" or the integer 1 is refused, not read as true)."""

    def accepts(self, value) -> bool:
        return _is_bool(value)

    def describe(self) -> str:
        return "True or False"


class NoneValue(Constraint):
    """None (the setting's "not given")."""

    def accepts(self, value) -> bool:
        return value is None

    def describe(self) -> str:
        return "None"


class Instance(Constraint):
    """An instance of one of ``types`` (with a description, since a type's name is rarely what a user reads)."""

    def __init__(self, *types, description=None):
        self.types = types
        self.description = description or "an instance of " + " or ".join(t.__name__ for t in types)

    def accepts(self, value) -> bool:
        return isinstance(value, self.types)

    def describe(self) -> str:
        return self.description


class Check(Constraint):
    """A value ``check`` accepts: ``check(value)`` raises ``ValueError`` (or ``TypeError``) when it does
    not; ``description`` says what it accepts. For settings whose grammar is parsed by a function that
    already exists (a latent model string, say), so that the grammar is stated once. ``explain=True``:
    the check's own message (which coefficient, which unit) is added to the error."""

    def __init__(self, check: _Callable, description: str, explain: bool = False):
        self.check, self.description, self._explain = check, description, explain

    def _error(self, value) -> Exception | None:
        try:
            self.check(value)
        except (ValueError, TypeError) as e:
            return e
        return None

    def accepts(self, value) -> bool:
        return self._error(value) is None

    def describe(self) -> str:
        return self.description

    def explain(self, value) -> str | None:
        if not self._explain:
            return None
        e = self._error(value)
        return None if e is None else str(e).splitlines()[0] if str(e) else type(e).__name__


class Terms(Check):
    """A non-empty subset of ``allowed`` (default Q, N, B, K, R) without repeats, as a string ("NBK") or
    a list; ``why`` says why a coefficient is not allowed (it is added to the description)."""

    def __init__(self, allowed: str = "QNBKR", why: str | None = None):
        from avbench.estimators.validation import check_terms

        def check(value):
            terms = check_terms(value)
            outside = [c for c in terms if c not in allowed]
            if outside:
                raise ValueError(f"terms: {', '.join(outside)} not allowed")

        what = f"a non-empty subset of {', '.join(allowed)} without repeats, e.g. 'NBK'"
        super().__init__(check, what + (f" ({why})" if why else ""))


class Taus(Check):
    """"octave", "decade", "all" or a non-empty list of positive seconds."""

    def __init__(self):
        from avbench.estimators.validation import check_taus

        super().__init__(check_taus, "'octave', 'decade', 'all' or a non-empty list of positive seconds")


def _check_coefficients(value, positive: bool = False) -> None:
    from avbench.noise_models.units import COEFFICIENTS, as_si

    if not isinstance(value, Mapping) or not value:
        raise ValueError("not a mapping")
    for c, v in value.items():
        if c not in COEFFICIENTS:
            raise ValueError(f"unknown coefficient {c!r}")
        si = as_si(c, v)
        if not (math.isfinite(si) and si >= 0):
            raise ValueError(f"{c}: not a finite value >= 0")
        if positive and not si > 0:
            raise ValueError(f"{c}: 0, expected a positive value")


class Coefficients(Check):
    """A mapping coefficient -> value (SI, or a ``(value, unit)`` pair), each finite and >= 0 (> 0 with
    ``positive=True``: starting values, where a term at 0 would never move)."""

    def __init__(self, positive: bool = False):
        bound = "> 0" if positive else ">= 0"
        super().__init__(lambda value: _check_coefficients(value, positive),
                         f"a mapping of Q, N, B, K, R to values {bound} (SI, or (value, 'unit') pairs)",
                         explain=True)


class Relation:
    """A relation between settings ``names`` of one estimator: ``check(estimator)`` raises ``ValueError``
    naming the setting when a configured (unfitted) estimator breaks it; ``description`` says what holds."""

    def __init__(self, names, check: _Callable, description: str):
        self.names, self.check, self.description = tuple(names), check, description

    def __repr__(self) -> str:
        return f"<{', '.join(self.names)}: {self.description}>"


def allowed(cls) -> list[str]:
    """The settings ``cls`` accepts: those it declares, in its ``__init__`` order (all of its ``__init__``
    settings where it declares none)."""
    names = cls._param_names()
    declared = getattr(cls, "parameter_constraints", None)
    return names if declared is None else [p for p in names if p in declared]


def undeclared(cls) -> list[str]:
    """The settings of ``cls`` (its ``__init__`` keywords) that its ``parameter_constraints`` does not declare."""
    declared = getattr(cls, "parameter_constraints", None) or {}
    return [p for p in cls._param_names() if p not in declared]


def validate_settings(cls, params: dict) -> None:
    """Check ``params`` (setting -> value; the settings not given take their defaults) of estimator class
    ``cls``: each is one it accepts (:func:`allowed`), each value passes its ``parameter_constraints``, and
    the settings keep the class's ``setting_relations``. A ``ValueError`` names the estimator and the
    first bad setting with what it accepts (for an unknown one: the accepted settings)."""
    declared = getattr(cls, "parameter_constraints", None) or {}
    name = getattr(cls, "name", cls.__name__)
    accepted = allowed(cls)
    unknown = sorted(set(params) - set(accepted))
    if unknown:
        raise ValueError(f"estimator {name!r}: unknown setting(s) {', '.join(unknown)}; "
                         f"accepted: {', '.join(accepted) or '(none)'}")
    for key, value in params.items():
        constraints = declared.get(key)
        if constraints is None:
            continue
        if any(c.accepts(value) for c in constraints):
            continue
        expected = " or ".join(c.describe() for c in constraints)
        why = [w for w in (c.explain(value) for c in constraints) if w]
        reason = f" ({'; '.join(why)})" if why else ""
        raise ValueError(f"estimator {name!r}: {key}={_short(value)}: expected {expected}{reason}")
    relations = getattr(cls, "setting_relations", ())
    if relations:
        est = cls(**params)
        for relation in relations:
            try:
                relation.check(est)
            except (ValueError, TypeError) as e:
                raise ValueError(f"estimator {name!r}: {e}") from None


def _short(value, limit: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
