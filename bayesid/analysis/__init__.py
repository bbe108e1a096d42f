"""Analysis layer: what the data say about a model.

* :mod:`bayesid.analysis.gap`: the sim-to-real gap diagnosis (where / candidates / verdict /
  support, orchestrated by :func:`bayesid.analysis.gap.diagnose`).
"""
