"""Study recipes: one module per way of running a study (see :mod:`rlgsim.sim.study`).

Every module here is a recipe (it has ``check`` and ``run``) except the building blocks
listed in :data:`SHARED`.
"""

import pkgutil

#: Modules of this package that recipes share and that are not recipes themselves.
SHARED = ("single_gyro", "environments_report")


def recipe_names() -> tuple[str, ...]:
    """The recipe modules of this package, sorted."""
    return tuple(sorted(m.name for m in pkgutil.iter_modules(__path__)
                        if not m.name.startswith("_") and m.name not in SHARED))
