"""The ground both sides stand on: the vocabulary ``rlgsim.sim`` and ``rlgsim.estimators``
share, written once.

- :mod:`~rlgsim.ground.units` — SI constants and every unit conversion;
- :mod:`~rlgsim.ground.errors` — :class:`UserInputError`, the one-line user mistake;
- :mod:`~rlgsim.ground.earth` — WGS-84 normal gravity and the Earth rate at a site;
- :mod:`~rlgsim.ground.frames` — rotations and the turntable gimbal convention;
- :mod:`~rlgsim.ground.dataset_format` — the dataset's format marker, version, names and reader.

Nothing here imports ``rlgsim.sim`` or ``rlgsim.estimators``.
"""
