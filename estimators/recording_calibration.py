"""The calibration campaign on a recording (docs/recordings.md): a recording's pulses and
probes plus its commanded turntable programme, read through the same interface as
:class:`rlgsim.estimators.calibration.DatasetReader`, so :func:`~rlgsim.estimators.calibration.
run_campaign` calibrates a recording exactly as it calibrates a simulated dataset (same
windows, same filter settings from the same noise keys, same table).

The programme's times are in the recording's clock (its ``time_s``); sample ``k`` covers
``[start + k/f, start + (k+1)/f)`` with ``start = time_s[0] − 1/f``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from rlgsim.estimators.calibration import (DEFAULT_ACCEL_SF_PULSE_PER_S_PER_G,
                                           DEFAULT_GYRO_SF_PULSE_PER_ARCSEC, G0, CampaignError)
from rlgsim.estimators.strapdown import ARCSEC, SensorModel
from rlgsim.ground.recording import Recording, load_recording

__all__ = ["RecordingSource", "RecordingReader"]


class RecordingReader:
    """What the campaign reads (see DatasetReader), from a loaded :class:`Recording` and the
    programme's timeline ``segments``."""

    def __init__(self, recording: Recording, segments: list[dict]) -> None:
        rec = recording
        self.rec = rec
        self.path = str(rec.path)
        if rec.gyro_axes != ["x", "y", "z"] or rec.accel_axes != ["x", "y", "z"]:
            raise CampaignError(f"{rec.path}: the turntable calibration needs gyro and "
                                f"accelerometer columns for axes x, y, z; the recording has "
                                f"gyro {rec.gyro_axes or 'none'}, accelerometer "
                                f"{rec.accel_axes or 'none'}")
        for a, v in rec.sidecar.orientation.items():
            if not np.allclose(v, np.eye(3)["xyz".index(a)] if a in "xyz" else 0):
                raise CampaignError(f"{rec.sidecar.path}: orientation.{a}: the calibration "
                                    f"assumes the body frame is East-North-Up at zero table "
                                    f"angles (docs/recordings.md)")
        self.latitude_deg = rec.sidecar.latitude_deg
        self.height_m = rec.sidecar.height_m
        self.rate_hz = rec.sample_rate_hz
        self.n_samples = rec.n_samples
        self._segments = segments
        self._gyro = rec.gyro_pulses()
        self._accel = rec.accel_pulses()
        self._ptimes, self._ptemps = rec.probes()

    def close(self) -> None:
        pass

    def nominal(self) -> SensorModel:
        sc = self.rec.sidecar
        kg = sc.gyro_sf_pulse_per_arcsec or DEFAULT_GYRO_SF_PULSE_PER_ARCSEC
        ka = sc.accel_sf_pulse_per_s_per_g or DEFAULT_ACCEL_SF_PULSE_PER_S_PER_G
        return SensorModel.nominal(kg / ARCSEC, ka / G0)

    def noise(self) -> dict[str, float]:
        return dict(self.rec.sidecar.noise)

    def segments(self) -> list[dict]:
        return list(self._segments)

    def sample_range(self, t0_s: float, t1_s: float) -> tuple[int, int]:
        s = self.rec.start_s
        return int(round((t0_s - s) * self.rate_hz)), int(round((t1_s - s) * self.rate_hz))

    def pulses(self, t0_s: float, t1_s: float) -> tuple[np.ndarray, np.ndarray]:
        k0, k1 = self.sample_range(t0_s, t1_s)
        if k0 < 0:
            raise ValueError(f"the window starts at {t0_s:.1f} s, before the recording "
                             f"({self.rec.start_s:.1f} s)")
        if k1 > self.n_samples:
            raise ValueError(f"the recording ends at {self.rec.start_s + self.rec.duration_s:.1f}"
                             f" s, the window needs {t1_s:.1f} s")
        return self._gyro[k0:k1], self._accel[k0:k1]

    def probe_names(self) -> list[str]:
        return self.rec.probe_names

    def probes(self, t0_s: float, t1_s: float) -> np.ndarray:
        t = self._ptimes
        rows = slice(int(np.searchsorted(t, t0_s, side="right")),
                     int(np.searchsorted(t, t1_s, side="right")))
        return self._ptemps[rows]

    def truth(self, t0_s: float, t1_s: float) -> None:
        return None                          # a recording has no ground truth


@dataclass(frozen=True)
class RecordingSource:
    """A recording and its programme, as :func:`run_campaign` takes it in place of a dataset
    path (picklable: worker processes load the recording themselves)."""

    path: str
    segments: tuple

    def __post_init__(self) -> None:
        object.__setattr__(self, "path", os.fspath(self.path))
        object.__setattr__(self, "segments", tuple(self.segments))

    def __str__(self) -> str:
        return self.path

    def open(self) -> RecordingReader:
        return RecordingReader(load_recording(self.path), list(self.segments))
