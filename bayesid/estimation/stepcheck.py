"""Is the model step fine enough for the data? A step-halving check of a fit (issue 50).

The models integrate with a fixed-step RK4 whose inputs are averaged over each step
(:mod:`bayesid.models.context`), second order in the step where the inputs move. On runs logged
finely and precisely the estimate is so narrow that this discretisation bias moves it by
several sd, while the track fit looks perfect: NPS AUV II zigzags logged at 10-20 Hz and fitted at
its 0.5 s default step put the truth outside the joint 90 % region in every one of six seeds
(Mahalanobis d^2 30-140 against the chi^2_6 quantile 10.6), and at 0.1 s inside it in 12 of 12
(``benchmarks/log_rate_coverage.py``).

The check is Richardson's step halving (e.g. Hairer, Norsett & Wanner 1993, "Solving Ordinary
Differential Equations I", Sec. II.4) carried to the estimate: the fit's residuals ``r_h`` with
the step halved, at the fitted parameters (window start states refitted), against those at the
fitted step ``r``; one Gauss-Newton step with the fit's Jacobian ``J`` (start states projected
out) gives the shift of the estimate that halving the step would cause,

    delta = -J^+ (r_h - r),

reported per free coefficient in units of its Laplace sd and as a Mahalanobis distance
``d^2 = delta' C^-1 delta``, whose root is the largest shift in sd along any direction of the
parameters (a combination of correlated coefficients can move by many of its sds while each
coefficient moves by less than one of its own). Where ``sqrt(d^2)`` exceeds :data:`STEP_SHIFT_SD`
the intervals are not honest at that step; ``bayesid fit --dt auto`` halves it and refits until
the shift is below the tolerance (:data:`MAX_HALVINGS` at most).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from ..data.validate import BayesidWarning
from .windows import WindowObjective


class StepWarning(BayesidWarning):
    """The model step is too coarse for the data (:attr:`StepCheck.too_coarse`): raised by
    :func:`bayesid.identify` where ``bayesid fit`` prints the same sentence."""


__all__ = ["MAX_HALVINGS", "STEP_SHIFT_SD", "StepCheck", "StepWarning", "step_check"]

#: The largest shift of the estimate, in sd along any direction (the root of its Mahalanobis
#: distance), that halving the model step may cause before the step counts as too coarse for the
#: data: a 0.5 sd bias lowers the coverage of a 90 % interval to 86 %, and of the joint 90 %
#: region of six coefficients to 88 %.
STEP_SHIFT_SD = 0.5
#: Halvings of the model step ``--dt auto`` tries at most (0.5 s -> 0.0625 s).
MAX_HALVINGS = 3


@dataclass
class StepCheck:
    """The step-halving check of a fit (module docstring).

    Parameters
    ----------
    dt : float
        The fit's model step, s.
    dt_check : float
        The halved step the residuals were compared at, s.
    shift_sd : dict
        ``{coefficient: shift / Laplace sd}`` the halving would cause.
    max_shift_sd : float
        The largest ``|shift_sd|`` (NaN: not computed).
    worst : str
        The coefficient with it.
    d2 : float
        The Mahalanobis distance of the shift, ``delta' C^-1 delta`` (over the coefficients
        with a positive sd).
    steps_tried : list of float
        The steps fitted, coarsest first (one entry unless ``--dt auto`` refined it).
    """

    dt: float
    dt_check: float
    shift_sd: dict = field(default_factory=dict)
    max_shift_sd: float = float("nan")
    worst: str = ""
    d2: float = float("nan")
    steps_tried: list = field(default_factory=list)

    @property
    def too_coarse(self) -> bool:
        """True when halving the step moves the estimate by more than :data:`STEP_SHIFT_SD` sd
        along some direction (``sqrt(d2)``)."""
        return bool(self.d2 > STEP_SHIFT_SD**2)

    def to_dict(self) -> dict:
        """The check as a JSON-able dict (``model.json``'s ``fit.step_check``).

        Returns
        -------
        dict
            The fields, ``tolerance_sd`` and ``too_coarse``.
        """
        return {**asdict(self), "tolerance_sd": STEP_SHIFT_SD, "too_coarse": self.too_coarse}

    def sentence(self) -> str:
        """The check in words, for a report or a warning.

        Returns
        -------
        str
            One sentence: the step, the largest shift halving it causes, the verdict.
        """
        tried = ""
        if len(self.steps_tried) > 1:
            tried = (
                f" (refined from {self.steps_tried[0]:g} s: " + " -> ".join(f"{s:g}" for s in self.steps_tried) + ")"
            )
        if not math.isfinite(self.d2):
            return f"model step {self.dt:g} s{tried}: the step-halving check could not be computed"
        verdict = f"within the {STEP_SHIFT_SD:g} sd tolerance"
        if self.too_coarse:
            verdict = f"more than the {STEP_SHIFT_SD:g} sd tolerance: the step is coarse for these data " + (
                f"(still after {len(self.steps_tried) - 1} halvings: intervals too narrow by the shift)"
                if len(self.steps_tried) > MAX_HALVINGS
                else "(--dt auto halves it)"
            )
        return (
            f"model step {self.dt:g} s{tried}: halving it to {self.dt_check:g} s moves {self.worst} by "
            f"{self.shift_sd.get(self.worst, float('nan')):+.2f} sd and the estimate by {math.sqrt(self.d2):.2g} sd "
            f"along its most moved direction (Mahalanobis), {verdict}"
        )


def _residuals(model, ctxs, sd, x, channels, prior, window_starts) -> np.ndarray:
    """The fit's residual vector at ``x`` on ``ctxs`` (start states refitted, warm-started from
    ``window_starts`` where their shapes fit the windows)."""
    ob = WindowObjective(model, ctxs, sd, channels=channels, prior=prior)
    if window_starts is not None:
        ob.warm_start(
            [
                s if s is not None and c.start == "fitted" and np.shape(s) == (c.W, 6) else None
                for s, c in zip(window_starts, ctxs)
            ]
        )
    return ob.residuals(np.asarray(x, float))[0]


def step_check(fitres, cov, problem, rebuild) -> StepCheck:
    """The step-halving check of a fit (module docstring).

    Parameters
    ----------
    fitres : FitResult
        The fit (its ``x``, ``jac``, ``window_starts`` and ``model``).
    cov : ndarray, shape (n_params, n_params)
        Its Laplace covariance.
    problem : WindowProblem
        The fit's problem (contexts, channel weights, channels, prior of a MAP fit).
    rebuild : callable
        ``rebuild(dt) -> (model, ctxs)``: the same model and contexts at another step.

    Returns
    -------
    StepCheck
        The shift of each free coefficient in sd; NaN where the residual vectors at the two
        steps do not line up or a simulation diverged.
    """
    model = problem.model
    dt, dt2 = float(model.dt), float(model.dt) / 2.0
    out = StepCheck(dt=dt, dt_check=dt2, steps_tried=[dt])
    if fitres.jac is None:
        return out
    args = (problem.sd, fitres.x, problem.channels, problem.prior, fitres.window_starts)
    r = _residuals(model, problem.ctxs, *args)
    model2, ctxs2 = rebuild(dt2)
    r2 = _residuals(model2, ctxs2, *args)
    J = fitres.jac.toarray() if hasattr(fitres.jac, "toarray") else np.asarray(fitres.jac)
    if r.shape != r2.shape or J.shape[0] != r.size or not (np.all(np.isfinite(r)) and np.all(np.isfinite(r2))):
        return out
    delta = -np.linalg.lstsq(J, r2 - r, rcond=None)[0][: model.n_params]
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    ok = sd > 0
    z = np.where(ok, delta / np.where(ok, sd, 1.0), 0.0)
    names = list(model.param_names)
    k = int(np.argmax(np.abs(z)))
    sub = np.flatnonzero(ok)
    d2 = float(delta[sub] @ np.linalg.lstsq(cov[np.ix_(sub, sub)], delta[sub], rcond=None)[0]) if sub.size else 0.0
    out.shift_sd = {n: float(v) for n, v in zip(names, z)}
    out.max_shift_sd, out.worst, out.d2 = float(abs(z[k])), names[k], d2
    return out
