"""The inertial navigator: strapdown mechanization on WGS-84 (ENU), alignment, error helpers.

``from rlgsim.estimators.ins import InsState, integrate, coarse_align, fine_align``.
docs/navigation.md describes the frames, the algorithms and their sources.
"""

from rlgsim.estimators.ins.mechanization import (InsSolution, InsState, increments_from_pulses,
                                                 integrate)

from rlgsim.estimators.ins.alignment import (Alignment, align, attitude_error, coarse_align,
                                             heading_error_bound)

__all__ = ["Alignment", "InsSolution", "InsState", "align", "attitude_error", "coarse_align",
           "heading_error_bound", "increments_from_pulses", "integrate"]
