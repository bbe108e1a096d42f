"""Estimation layer: what every fit and posterior of the package shares.

* :mod:`.fit`: the one fit function (least squares or SLSQP) and its :class:`~.fit.FitResult`.
* :mod:`.objective`: the paper's whole-track output-error objective (Problem, JointProblem).
* :mod:`.windows`: the multiple-shooting objective of a model on tracks, weighted fits, scores.
* :mod:`.shooting`: window start states fitted with the model (variable projection).
* :mod:`.laplace`: the Gauss-Newton (Laplace) covariance (prior and AR(1) inflation optional).
* :mod:`.posterior`: priors and the vectorised log-posterior; :mod:`.sampling`: emcee ensembles
  with HDF5 checkpoints and ArviZ diagnostics.
* :mod:`.msfit`: identification and prediction on long runs, manoeuvre indices, model.json.
"""
