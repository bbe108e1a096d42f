"""Estimation layer: what every fit and posterior of the package shares.

* :mod:`.fit`: the one fit function (least squares or SLSQP) and its :class:`~.fit.FitResult`.
* :mod:`.objective`: the paper's whole-track output-error objective (Problem, JointProblem).
* :mod:`.windows`: the multiple-shooting objective of a model on tracks, weighted fits, scores.
* :mod:`.shooting`: window start states fitted with the model (variable projection).
* :mod:`.laplace`: the Gauss-Newton (Laplace) covariance and that of a multiple-shooting fit (AR(1) inflation).
* :mod:`.posterior`: priors and the vectorised log-posterior; :mod:`.sampling`: emcee ensembles
  with HDF5 checkpoints and ArviZ diagnostics.
* :mod:`.options`: the options of a fit and of its calibration (:class:`~.options.FitOptions`,
  :class:`~.options.CalibrationOptions`).
* :mod:`.identification`: identification on long runs (:func:`~.identification.identify`, its
  :class:`~.identification.IdentifyResult`); :mod:`.modelfile`: ``model.json``
  (:class:`~.modelfile.ModelDocument`); :mod:`.prediction`: prediction under the window protocol
  and of manoeuvre indices; :mod:`.indices`: the manoeuvre indices;
  :mod:`.calibration`: predictive bands calibrated leave one run out;
  :mod:`.multistart`: many starts of one fit; :mod:`.track_posterior`: the posterior given a
  user's tracks (``bayesid sample``).
"""
