"""The package layout (pyproject.toml holds everything else): one import package, ``avbench``, whose
subpackages are the repository's top-level folders -- ``noise_models/`` installs as
``avbench.noise_models``, and so on. Every package under those folders is found, none listed by hand."""

from setuptools import find_namespace_packages, setup

#: the top-level folders that are subpackages of avbench (avbench/ itself holds the package root)
FOLDERS = ("noise_models", "estimators", "studies", "recordings", "bench")

package_dir = {"avbench": "avbench"}
packages = ["avbench"]
for folder in FOLDERS:
    package_dir[f"avbench.{folder}"] = folder
    # namespace packages too: a folder of data files (studies/paper_tables) is a package of its own
    found = find_namespace_packages(folder, exclude=["*__pycache__*"])
    packages += [f"avbench.{folder}"] + [f"avbench.{folder}.{sub}" for sub in found]

setup(package_dir=package_dir, packages=packages)
