"""Every docstring example of the installed package runs, and prints what it says it prints.

The modules are found by walking the installed ``avbench`` with :mod:`pkgutil` (its subpackages
too: an editable install maps each to its own folder, a wheel puts them under ``avbench/``) and
imported; each module with examples is one test, run by :class:`doctest.DocTestRunner` with
``ELLIPSIS`` and ``NORMALIZE_WHITESPACE`` in the module's own namespace (doctest's rule), with
matplotlib on Agg. A module that cannot be imported because an optional dependency is missing is
skipped with that reason; any other import error fails. A ``__main__`` module is read, not
imported (importing it runs the command): one with examples is skipped, saying so.
"""

from __future__ import annotations

import ast
import doctest
import importlib
import importlib.util
import io
import os
import pkgutil
import sys
from pathlib import Path

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")

import avbench  # noqa: E402

FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE

#: modules whose examples are known to fail, each with what would mend it: strict xfails, so an example
#: that passes fails the test until its entry is removed here (none)
KNOWN_FAILING: dict[str, str] = {}


def _module_names() -> tuple[list[str], dict[str, BaseException]]:
    """Every module of the installed package, and the packages pkgutil could not import (name -> error)."""
    names, broken = [], {}

    def onerror(name):  # pkgutil calls it inside the except clause of the failed import
        broken[name] = sys.exc_info()[1] or ImportError(f"{name}: import failed while walking the package")

    def walk(package):
        names.append(package.__name__)
        names.extend(m.name for m in pkgutil.walk_packages(package.__path__, package.__name__ + ".", onerror))

    walk(avbench)
    for sub in avbench._SUBPACKAGES:  # lazily loaded: on avbench.__path__ only in a wheel
        name = f"avbench.{sub}"
        if name not in names:
            walk(importlib.import_module(name))
    return sorted(set(names)), broken


def _examples_in_source(path: str) -> bool:
    tree = ast.parse(Path(path).read_text())
    nodes = [tree] + [n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))]
    return any(">>>" in (ast.get_docstring(n) or "") for n in nodes)


def _params():
    names, broken = _module_names()
    params = []
    finder = doctest.DocTestFinder()
    for name in names:
        marks = []
        if name in KNOWN_FAILING:
            marks.append(pytest.mark.xfail(reason=KNOWN_FAILING[name], strict=True))
        if name.endswith(".__main__") or name == "__main__":
            spec = importlib.util.find_spec(name)
            if spec and spec.origin and _examples_in_source(spec.origin):
                params.append(pytest.param(name, "main", id=name, marks=marks))
            continue
        try:
            module = importlib.import_module(name)
        except Exception as e:  # reported by the test: skipped for an optional dependency, else failed
            params.append(pytest.param(name, e, id=name, marks=marks))
            continue
        if any(t.examples for t in finder.find(module)):
            params.append(pytest.param(name, None, id=name, marks=marks))
    params += [pytest.param(name, error, id=name) for name, error in broken.items()]
    return params


PARAMS = _params()


def test_every_example_module_is_collected():
    """The walk reaches the subpackages: their examples are among the tests."""
    ids = {p.id for p in PARAMS}
    assert {"avbench.noise_models", "avbench.noise_models.gyro", "avbench.estimators.allan.variance"} <= ids


@pytest.mark.parametrize("name, import_error", PARAMS)
def test_docstring_examples(name, import_error):
    if import_error == "main":
        pytest.skip(f"{name} runs its command when imported: its examples are not run here")
    if isinstance(import_error, ModuleNotFoundError) and not str(import_error.name or "").startswith("avbench"):
        pytest.skip(f"{name} needs the optional dependency {import_error.name!r}, not installed here")
    if import_error is not None:
        pytest.fail(f"{name} cannot be imported: {import_error!r}")
    module = importlib.import_module(name)
    runner = doctest.DocTestRunner(optionflags=FLAGS)
    report = io.StringIO()
    failed = attempted = 0
    for test in doctest.DocTestFinder().find(module):
        if test.examples:
            result = runner.run(test, out=report.write)
            failed, attempted = failed + result.failed, attempted + result.attempted
    assert attempted > 0, f"{name}: no example ran"
    assert failed == 0, f"{failed} of {attempted} examples of {name} failed:\n{report.getvalue()}"
