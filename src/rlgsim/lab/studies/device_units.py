"""Drawn device coefficients in the preset's units, for the reports' "Device coefficients" table.

A dataset's truth group stores every drawn coefficient with its unit (``truth/coefficient_units``,
docs/dataset.md): the temperature laws already in the preset's units (``deg_per_h/K``, ``v``),
the noise levels in SI (``rad/s^0.5``). The reports show them as a preset is written: the noise
levels converted back to the preset keys' units (``gyro_arw_deg_per_sqrt_h`` → °/√h, sim/sensors/noise.py),
the unit names spelt as in the rest of the report (°/h, °C, V).
"""

from __future__ import annotations

import pathlib
import re

from rlgsim.ground import units as U

#: noise coefficient (``noise.<name>[axis]``) → (unit of its preset key, SI → that unit)
NOISE_UNITS = {
    "gyro_arw": ("°/√h", U.rad_per_sqrt_s_to_deg_per_sqrt_h),
    "gyro_bi": ("°/h", U.rad_per_s_to_deg_per_h),
    "gyro_rrw": ("°/h/√h", U.rad_per_s_per_sqrt_s_to_deg_per_h_per_sqrt_h),
    "accel_vrw": ("µg/√Hz", lambda x: x / U.ug_per_sqrt_hz_to_m_per_s2_per_sqrt_hz(1.0)),
    "accel_bi": ("µg", U.m_per_s2_to_ug),
    "accel_rrw": ("µg/√s", U.m_per_s2_to_ug),
}
_SPELLING = [(r"deg_per_h", "°/h"), (r"degC", "°C"), (r"\bv\b", "V"), (r"\^0\.5", "^½"),
             (r"\bdeg\b", "°")]


def coefficient_units(path: str | pathlib.Path) -> dict[str, str]:
    """``coefficient → unit`` of a dataset's truth group; empty for a recording or a file whose
    truth cannot be read."""
    from rlgsim.ground.dataset_format import TRUTH, open_dataset
    from rlgsim.ground.errors import UserInputError
    try:
        with open_dataset(path) as ds:
            return dict(zip(ds.strings(TRUTH, "coefficient"),
                            ds.strings(TRUTH, "coefficient_units")))
    except (UserInputError, OSError, KeyError, ValueError):
        return {}


def in_preset_units(name: str, value: float, unit: str) -> tuple[float, str]:
    """``(value, unit)`` of one coefficient as a preset writes it (module docstring)."""
    m = re.fullmatch(r"noise\.(\w+)\[\w+\]", name)
    if m and m.group(1) in NOISE_UNITS:
        label, convert = NOISE_UNITS[m.group(1)]
        return float(convert(value)), label
    for pattern, text in _SPELLING:
        unit = re.sub(pattern, text, unit)
    return value, unit
