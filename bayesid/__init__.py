"""bayesid: identify the hydrodynamic coefficients of manoeuvring vessels from their tracks,
with honest uncertainty.

Data flow (``ls bayesid/`` follows it): vehicle (``vehicle``, ``terms``) -> manoeuvre
(``manoeuvres``) -> simulate (``dynamics``, ``simulate``; ``reference`` is the slow anchor) ->
``track`` -> ``identify`` (SLSQP / least squares, the paper's Cases in ``cases``).
"""
__version__ = "0.1.0"
