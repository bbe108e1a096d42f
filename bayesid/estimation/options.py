"""Options of the identification steps, grouped as small frozen dataclasses (as scipy groups a
solver's options): what ``bayesid fit`` fits and how, and how its predictive bands are calibrated.

A step takes its options as one object; a resumable run's identity is the options'
:func:`dataclasses.asdict`, so an option added here is part of the identity without a hand-kept
list of keys.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from ..models.context import INPUT_RECONSTRUCTIONS

__all__ = ["CalibrationOptions", "FitOptions"]


def check_rudder_rate_reading(inputs: str, rudder_rate_deg_s) -> None:
    """Refuse a steering gear's rate given with a reading of the logged inputs that does not use it
    (only ``inputs="rate"`` reads it): the fit's and the gap diagnosis's options.

    Parameters
    ----------
    inputs : str
        The reading (``"hold"``, ``"linear"``, ``"rate"``).
    rudder_rate_deg_s : float or None
        The gear's rate, deg/s.

    Raises
    ------
    ValueError
        A rate with another reading than ``"rate"``, naming both options.
    """
    if rudder_rate_deg_s is not None and inputs != "rate":
        raise ValueError(
            f"--rudder-rate is the gear's rate of --inputs rate: with --inputs {inputs} it would not be used"
        )


@dataclass(frozen=True)
class FitOptions:
    """What a fit identifies and how (:func:`bayesid.estimation.identification.identify`).

    Parameters
    ----------
    free : tuple of str, optional
        The free coefficients (None: the vehicle file's ``[fit] free`` for a ship, none for a
        submarine); any sequence is stored as a tuple.
    effects : tuple of str, default ()
        The effects in the model (ship: :data:`bayesid.models.ship.SHIP_CATALOGUE`).
    window_s : float, optional
        The multiple-shooting window (s), positive; None: the family's ``default_fit_window``.
    dt : float, optional
        The model step (s), positive; None: the vehicle's default (:func:`bayesid.models.default_dt`).
    refine_step : bool, default False
        Halve the model step and refit while halving it would move the estimate by more than
        :data:`bayesid.estimation.stepcheck.STEP_SHIFT_SD` sd along some direction (``bayesid fit --dt
        auto``; :mod:`bayesid.estimation.stepcheck`). Every fit runs the check; this acts on it.
    max_nfev : int, default 60
        Least-squares iterations of each fit, at least 1.
    equation_error_seed : bool, default True
        Start from the model's equation-error estimate (``model.seed``; ships) when it
        simulates better than the nominal coefficients.
    weighting : str, optional
        ``"noise"`` or ``"residual"`` channel weights
        (:func:`bayesid.estimation.windows.fit_weighted`); None: the family's default.
    channels : tuple of str, optional
        The scored channels (None: every one the tracks measure).
    start : str, default "auto"
        The window start-state rule (:data:`bayesid.protocol.START_RULES`).
    starts : int, default 0
        Extra Latin-hypercube starts of a multistart fit (0: the default start alone).
    random_seed : int, default 0
        Seed of the multistart starts.
    prior : bool, default True
        Use the vehicle file's ``[prior]`` section when it has one (a MAP fit).
    inputs : str, default "hold"
        How the logged inputs (rudder, planes, propeller) are reconstructed between their
        samples (:data:`bayesid.models.context.INPUT_RECONSTRUCTIONS`): ``"hold"`` keeps each
        sample until the next (zero-order hold); ``"linear"`` interpolates linearly between
        samples, as a rate-limited rudder logged at its instantaneous angle moves. With a coarse
        log (1-5 Hz) of a moving rudder the hold makes the rudder act about half a sample late
        (issue 50); ``"rate"`` moves the control surfaces at the steering gear's rate between
        samples (:func:`bayesid.models.context.rate_limited_knots`), the propeller linearly. The
        model keeps it (``model.inputs``), so prediction and sampling of the fitted model read the
        inputs as the fit did.
    rudder_rate_deg_s : float, optional
        The gear's rate of ``inputs="rate"``, deg/s; default the vehicle file's (a ship's
        ``[service] rudder_rate_deg_s``).
    retime : bool, default False
        With ``inputs="rate"``: estimate, with the coefficients, when each rudder movement that
        lies within one log interval happened, and count their uncertainty in the coefficients'
        covariance (:mod:`bayesid.estimation.retiming`; ``bayesid fit --retime``).

    Raises
    ------
    ValueError
        ``max_nfev`` below 1, negative ``starts``, a non-positive ``window_s``, ``dt`` or
        ``rudder_rate_deg_s``, an unknown ``inputs``, ``retime`` or ``rudder_rate_deg_s`` without
        ``inputs="rate"``.
    """

    free: tuple | None = None
    effects: tuple = ()
    window_s: float | None = None
    dt: float | None = None
    refine_step: bool = False
    max_nfev: int = 60
    equation_error_seed: bool = True
    weighting: str | None = None
    channels: tuple | None = None
    start: str = "auto"
    starts: int = 0
    random_seed: int = 0
    prior: bool = True
    inputs: str = "hold"
    rudder_rate_deg_s: float | None = None
    retime: bool = False

    def __post_init__(self):
        for name in ("free", "effects", "channels"):
            v = getattr(self, name)
            if v is not None and not isinstance(v, tuple):
                object.__setattr__(self, name, tuple(v))
        if int(self.max_nfev) < 1:
            raise ValueError(f"FitOptions.max_nfev must be at least 1, not {self.max_nfev}")
        if int(self.starts) < 0:
            raise ValueError(f"FitOptions.starts must be 0 or more, not {self.starts}")
        for name in ("window_s", "dt", "rudder_rate_deg_s"):
            v = getattr(self, name)
            if v is not None and not v > 0:
                raise ValueError(f"FitOptions.{name} must be positive, not {v}")
        if self.inputs not in INPUT_RECONSTRUCTIONS:
            raise ValueError(
                f"FitOptions.inputs must be one of {', '.join(INPUT_RECONSTRUCTIONS)}, not {self.inputs!r}"
            )
        check_rudder_rate_reading(self.inputs, self.rudder_rate_deg_s)
        if self.retime and self.inputs != "rate":
            raise ValueError(
                "--retime estimates the rudder's movements at the gear's rate: it needs --inputs rate "
                f"(FitOptions.inputs is {self.inputs!r})"
            )

    def to_dict(self) -> dict:
        """The options as a JSON-able dict (a run's identity).

        Returns
        -------
        dict
            ``{field: value}``, tuples as lists.
        """
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}


@dataclass(frozen=True)
class CalibrationOptions:
    """How a fit calibrates its predictive bands leave one run out
    (:func:`bayesid.estimation.calibration.leave_one_run_out`).

    Parameters
    ----------
    window_s : float, default 60.0
        The protocol window of the window scores (s): the bands hold for windows of this length.
    draws : int, default 40
        Posterior draws of each fold for the index spreads (at least 3).
    seed : int, default 0
        Seed of those draws (fold ``g`` uses ``seed + g``).
    max_folds : int, default 10
        With more runs than this, run ``i`` is left out in fold ``i % max_folds`` (at least 3).

    Raises
    ------
    ValueError
        A non-positive window, fewer than 3 draws or fewer than 3 folds.
    """

    window_s: float = 60.0
    draws: int = 40
    seed: int = 0
    max_folds: int = 10

    def __post_init__(self):
        if not self.window_s > 0 or int(self.draws) < 3:
            raise ValueError(
                "CalibrationOptions needs a positive window and at least 3 draws, not "
                f"{self.window_s:g} and {self.draws}"
            )
        if int(self.max_folds) < 3:
            raise ValueError(f"CalibrationOptions.max_folds must be at least 3, not {self.max_folds}")

    def to_dict(self) -> dict:
        """The options as a JSON-able dict (a run's identity).

        Returns
        -------
        dict
            ``{field: value}``.
        """
        return asdict(self)
