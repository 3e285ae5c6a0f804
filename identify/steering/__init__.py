"""Linear steering dynamics from sea-trial records by output error and maximum likelihood
(Källström 1977, LISPID on the tanker Sea Splendour): Nomoto and sway-yaw state-space models
sampled exactly on irregular time grids, Kalman-predictor likelihood, AIC, residual tests and the
derivative -> transfer-function mappings.

- :mod:`identify.steering.mappings`: Tables 3.3/3.6/4.2's mappings.
- :mod:`identify.steering.models`: model structures and their exact zero-order-hold sampling.
- :mod:`identify.steering.kalman`: the predictor/simulator time loop (numba when available).
- :mod:`identify.steering.estimate`: output error and maximum likelihood, standard errors, AIC.
- :mod:`identify.steering.crossval`: split at a course change and cross-validate (Tables 3.5-3.8).
- :mod:`identify.steering.recording`: steering records from CSV (stamps as they are) and MARIN .dat.
- :mod:`identify.steering.residuals`: whiteness and input cross-correlation tests.
- :mod:`identify.steering.api`: the library call behind ``shiptrial steering``; :mod:`identify.steering.report`
  its text, JSON and plots.
"""
