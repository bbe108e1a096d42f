"""Estimation layer: what every fit and posterior of the package shares.

* :mod:`bayesid.estimation.laplace`: the Gauss-Newton (Laplace) covariance of fitted parameters
  from a weighted Jacobian, with an optional Gaussian prior precision and an optional inflation
  for correlated residuals.
"""
