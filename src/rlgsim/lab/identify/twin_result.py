"""What an identification returns (:func:`rlgsim.lab.identify.twin.identify`): where the
outputs went and what was fitted — one module that the single-gyro and the several-gyro
identifications (:mod:`.twin`, :mod:`.twin_gyros`) both build it from."""

from __future__ import annotations

import pathlib
from dataclasses import dataclass

from rlgsim.lab.identify.law_fit import LawFit
from rlgsim.lab.identify.recording_data import RecordingData
from rlgsim.lab.identify.scale_factor_fit import ScaleFactorFit
from rlgsim.lab.identify.thermal_fit import ThermalFit

__all__ = ["Identification"]


@dataclass
class Identification:
    """Where the outputs went and what was fitted."""

    out_dir: pathlib.Path
    device_path: pathlib.Path
    thermal_path: pathlib.Path
    scenario_path: pathlib.Path
    report_path: pathlib.Path
    data: RecordingData
    thermal: ThermalFit
    laws: LawFit
    device: dict
    thermal_preset: dict
    seconds: float
    name: str
    #: the scale-factor law from the turntable's rate segments (None: a static recording)
    scale_factor: ScaleFactorFit | None = None
    #: how the recorded probes were placed on the template's (empty: named as the template)
    probe_lines: tuple[str, ...] = ()
    #: defaults taken for what the recording's sidecar does not say (sidecar_choices)
    notes: tuple[str, ...] = ()
    #: the next experiment (``suggest_programme``; None: not asked, or nothing to separate)
    suggestion: object = None
    next_path: pathlib.Path | None = None
    gyros: tuple = ()        # every gyro of a several-gyro twin (twin_gyros.GyroTwin)
    next_gyro: str | None = None   # the gyro a several-gyro twin's next experiment is for
