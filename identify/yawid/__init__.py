"""Yaw-dynamics identification of a podded ship during operation (the podded-ship MSc thesis, chapters 2.4 and 4).

The yaw row of the 4-DOF model with the lumped parameters of section 2.4.2 -- the full model
(2.17) and the simplified model (2.18) -- is estimated by an output-error prediction-error method
(4.1)-(4.4): the predictor simulates r driven by the measured v_dot, u, v, phi and the measured pod
yaw moment. Modules: ``model`` (structures and true lumped values), ``experiment`` (manoeuvres and
simulated recordings), ``estimate`` (batched Levenberg-Marquardt with forward sensitivities),
``identifiability`` (section 2.4.2 checked numerically), ``recording`` (CSV in/out),
``montecarlo`` (the chapter-4 study).
"""
