"""The folder mapping of the one ``rlgsim`` namespace (everything else is in pyproject.toml).

Each source folder installs under ``rlgsim``; its subpackages are found afresh at each build, so a
new subpackage (a folder with an ``__init__.py``) is installed without editing a list.
"""

from setuptools import find_packages, setup

#: installed package -> source folder
PACKAGE_DIR = {
    "rlgsim": "src/rlgsim",
    "rlgsim.sim": "sim",
    "rlgsim.estimators": "estimators",
    "rlgsim.scenarios": "scenarios",
}


def _packages() -> list[str]:
    """Every installed package: each mapped folder and the subpackages found below it."""
    return sorted(name for package, folder in PACKAGE_DIR.items()
                  for name in (package, *(f"{package}.{sub}" for sub in find_packages(folder))))


setup(packages=_packages(), package_dir=PACKAGE_DIR)
