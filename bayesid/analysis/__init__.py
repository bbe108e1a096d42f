"""Analysis layer: what the data say about a model.

* :mod:`.identifiability`: sensitivities, Fisher information, sloppy directions, collinearity.
* :mod:`.dossier`: the identifiability dossier of a posterior.
* :mod:`.richness`: richness of manoeuvres and manoeuvre design.
* :mod:`.sindy`: model-free term check (ensemble SINDy), smoothed motion, inverse dynamics.
* :mod:`.gap`: the sim-to-real gap diagnosis (where / candidates / verdict / support,
  orchestrated by :func:`bayesid.analysis.gap.diagnose`).
"""
