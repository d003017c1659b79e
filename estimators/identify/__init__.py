"""Identification of a device from one recording (the digital twin, issue 17): the pure fitting
maths, usable on any data because it never imports the simulator.

Split between the two sides. The thermal grey-box fit needs the exact network integrator,
which lives in :mod:`rlgsim.sim` and which :mod:`rlgsim.estimators` must never import; so the
orchestration (read the recording, build candidate networks from a template, integrate them,
write the presets, the scenario and the report) lives in :mod:`rlgsim.lab.identify`, which may
import the estimators, while everything here works on plain arrays and callables:

- :mod:`.lsq_stats` — a nonlinear least-squares fit with standard errors and correlations from
  the Jacobian (inflated for autocorrelated residuals), and the identifiability screen that
  says which parameter the data cannot determine and why (rank-deficient Jacobian, pairwise
  correlation above a limit);
- :mod:`.term_selection` — forward selection of the terms of a law by the Bayesian information
  criterion (statsmodels OLS for the linear stage), then a joint refinement of the selected
  linear and nonlinear parameters (knee/step centres and widths) with their uncertainties;
- :mod:`.term_averaging` — the selection's uncertainty: model averaging over the linear subsets,
  the groups of terms a recording cannot separate, their combined effects and stand-ins;
- :mod:`.whitening` — the Cholesky whitening of the generalised least-squares fits;
- :mod:`.allan_noise` — angle random walk, bias instability, rate random walk and quantisation
  from the Allan deviation (allantools) of a rate residual, with confidence intervals.
"""
