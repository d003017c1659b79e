"""Study recipes and their building blocks (see :mod:`rlgsim.lab.study`).

A recipe is a module named in :data:`rlgsim.lab.study.RECIPES` with ``check``, ``run`` and an
optional ``report`` hook; the other modules here are the building blocks the recipes share
(docs/architecture.md lists them).
"""
