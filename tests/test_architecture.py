"""The architecture stays visible: no import cycles between avbench's modules, no module importing its
own package's ``__init__`` (which would hide a cycle behind the package), and no behaviour chosen by an
estimator's registry name outside the registry.

Imports are read from the source with :mod:`ast` (every ``import`` and ``from ... import``, at the
top of a module or inside a function: a lazy import still makes a dependency)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: repository folder -> import name (setup.py maps the folders onto avbench's subpackages)
FOLDERS = {"avbench": "avbench", "noise_models": "avbench.noise_models", "estimators": "avbench.estimators",
           "studies": "avbench.studies", "recordings": "avbench.recordings", "bench": "avbench.bench"}


def modules() -> dict[str, Path]:
    found = {}
    for folder, name in FOLDERS.items():
        for path in sorted((ROOT / folder).rglob("*.py")):
            parts = list(path.relative_to(ROOT / folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found[".".join([name, *parts])] = path
    return found


def import_graph(mods: dict[str, Path]) -> dict[str, set[str]]:
    """module -> the avbench modules it imports (a ``from P import x`` names P.x where that is a module)."""
    graph = {}
    for mod, path in mods.items():
        package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        targets = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(up + ([base] if base else []))
                names = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]
            else:
                continue
            targets.update(n for n in names if n in mods and n != mod)
        graph[mod] = targets
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as a list of modules (first == last), or None."""
    WHITE, GREY, BLACK = 0, 1, 2
    colour = dict.fromkeys(graph, WHITE)
    stack: list[str] = []

    def visit(u):
        colour[u] = GREY
        stack.append(u)
        for v in sorted(graph[u]):
            if colour[v] == GREY:
                return stack[stack.index(v):] + [v]
            if colour[v] == WHITE and (c := visit(v)):
                return c
        stack.pop()
        colour[u] = BLACK
        return None

    for u in sorted(graph):
        if colour[u] == WHITE and (c := visit(u)):
            return c
    return None


def test_the_cycle_finder_finds_cycles():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None


def test_no_import_cycles():
    cycle = find_cycle(import_graph(modules()))
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_no_module_imports_its_own_package():
    """A module importing its package's ``__init__`` (``from avbench.estimators import get`` inside
    avbench.estimators.x) depends on everything the package exports: it imports the defining module."""
    mods = modules()
    graph = import_graph(mods)
    bad = sorted(f"{m} imports {t}" for m, ts in graph.items() for t in ts if m.startswith(t + "."))
    assert not bad, "\n".join(bad)


def test_the_contract_depends_on_nothing_above_it():
    """avbench.estimators.base (the estimator contract) imports only noise_models and the estimators'
    leaves below it (validation, uncertainty, the five-term AV formula ``allan.model``, the typed result
    ``results`` and the declared settings ``settings``): never the AV engine, the fit check, a family or
    the studies."""
    graph = import_graph(modules())
    allowed = ("avbench.noise_models", "avbench.renamed", "avbench.estimators.validation",
               "avbench.estimators.uncertainty", "avbench.estimators.allan.model", "avbench.estimators.results",
               "avbench.estimators.settings")
    reached, todo = set(), ["avbench.estimators.base"]
    while todo:
        for t in graph[todo.pop()]:
            if t not in reached:
                reached.add(t)
                todo.append(t)
    above = sorted(t for t in reached if not t.startswith(allowed))
    assert not above, f"avbench.estimators.base reaches {above}"


NAME_CHOICE = re.compile(r"\.name\s*(==|in\s*\()")


def test_no_behaviour_chosen_by_an_estimator_name():
    """Figures, reports, the fit check and the studies ask an estimator (``model_avar``, its class
    attributes) instead of branching on its registry name; only the registry itself reads names."""
    registry = ROOT / "estimators" / "base.py"
    hits = [f"{p.relative_to(ROOT)}:{i}: {line.strip()}" for p in modules().values() if p != registry
            for i, line in enumerate(p.read_text().splitlines(), 1) if NAME_CHOICE.search(line)]
    assert not hits, "\n".join(hits)


def test_a_plugin_written_against_the_old_names_gets_a_clear_message(tmp_path):
    """A plugin module doing ``from estimators.base import Estimator`` (avbench before 0.2) is
    refused with a message that names the new import, not an ImportError deep inside."""
    import pytest

    from avbench.noise_models.plugins import PluginError, load_object

    (tmp_path / "old_style_plugin.py").write_text("from estimators.base import Estimator\n\nclass Mine(Estimator):\n    pass\n")
    with pytest.raises((PluginError, ImportError), match=r"from avbench\.estimators import"):
        load_object("old_style_plugin:Mine", tmp_path)


def test_estimators_draw_their_own_model():
    """``model_avar`` is the fitted model's AV: GMWM's Gauss-Markov model for gmwm and for
    gmwm_despiked alike (on a clean record they fit the same model and coefficients), never the
    five-term plateau a registry-name branch once drew for the latter."""
    import numpy as np

    from avbench import estimators
    from avbench.noise_models import AngleRandomWalk, GaussMarkov, Gyro

    g = Gyro(dt=0.01, terms=[AngleRandomWalk(N=1e-3), GaussMarkov(sigma=2e-4, tc=0.5)])
    rate = g.simulate(200_000, np.random.default_rng(3))
    tau = 0.01 * 2.0 ** np.arange(14)
    a = estimators.get("gmwm", model="WN+GM").fit(rate, 0.01)
    b = estimators.get("gmwm_despiked", model="WN+GM").fit(rate, 0.01)
    np.testing.assert_allclose(b.model_avar(tau), a.model_avar(tau), rtol=1e-3)
    # the fitted Gyro is that of the standardised record, whose unit is data_scale (Estimator.fit)
    np.testing.assert_allclose(a.model_avar(tau), a.diagnostics_["model"].avar(tau) * a.diagnostics_["data_scale"] ** 2)
    five_term = estimators.get("wls_edf").fit(rate, 0.01)
    from avbench.estimators.allan.model import model_avar

    c = five_term.coefficients_
    np.testing.assert_allclose(five_term.model_avar(tau), model_avar({k: v for k, v in c.items() if np.isfinite(v)}, tau))
