"""avbench's modules before 0.2 were four top-level packages (``import estimators``); they are now
subpackages of the one package ``avbench``. Code written against the old names (a plugin, a script)
gets :func:`moved`'s message instead of an ImportError deep inside: from the folders themselves when
a source checkout is on ``sys.path``, and from the plugin loader (:mod:`avbench.noise_models.plugins`)
when an installed plugin imports an old name.
"""

__all__ = ["OLD_NAMES", "moved"]

#: the top-level import names of avbench before 0.2 (``import estimators``): now avbench's subpackages
OLD_NAMES = ("noise_models", "estimators", "studies", "bench")


def moved(old: str) -> str:
    """The message for code (a plugin, a script) that imports avbench by a pre-0.2 name ``old``."""
    top = old.split(".")[0]
    return (f"{old!r} is avbench's pre-0.2 module name: since avbench 0.2 everything is imported from "
            f"the one package 'avbench' -- write 'from avbench.{top} import ...' (or 'from avbench import {top}') "
            f"instead of 'from {top} import ...' / 'import {top}'; docs/ARCHITECTURE.md lists where each module went")
