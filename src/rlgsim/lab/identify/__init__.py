"""Identification of a digital twin from one chamber recording (issue 17; docs/identify.md).

The orchestration lives here in :mod:`rlgsim.sim` because the thermal grey-box fit integrates
candidate networks with the simulator's exact integrator, which :mod:`rlgsim.estimators` may not
import; the fitting maths that needs no simulator (least squares with standard errors and the
identifiability screen, BIC term selection, the Allan noise fit) is in
:mod:`rlgsim.estimators.identify`, usable on its own.

- :mod:`.recording_data` — read and check the recording (one-line refusals);
- :mod:`.thermal_fit` — multipliers of the thermal template fitted on the exact integrator;
- :mod:`.law_fit` — bias and UHFO laws (BIC) on the twin's thermal state, noise (Allan);
- :mod:`.preset_text` — TOML of the presets and the replay scenario, every fitted number
  commented with its standard error;
- :mod:`.identify_report` — report.md / report.html;
- :mod:`.twin` — :func:`identify`, which runs them in that order.
"""

from rlgsim.lab.identify.twin import Identification, identify

__all__ = ["Identification", "identify"]
