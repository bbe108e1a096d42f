"""Options of the identification steps, grouped as small frozen dataclasses (as scipy groups a
solver's options): what ``bayesid fit`` fits and how, and how its predictive bands are calibrated.

A step takes its options as one object; a resumable run's identity is the options'
:func:`dataclasses.asdict`, so an option added here is part of the identity without a hand-kept
list of keys.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

__all__ = ["CalibrationOptions", "FitOptions"]


@dataclass(frozen=True)
class FitOptions:
    """What a fit identifies and how (:func:`bayesid.estimation.identify.identify`).

    Attributes
    ----------
    free : tuple of str or None
        The free coefficients (None: the vehicle file's ``[fit] free`` for a ship, none for a
        submarine).
    effects : tuple of str
        The effects in the model (ship: :data:`bayesid.models.ship.SHIP_CATALOGUE`).
    window_s : float or None
        The multiple-shooting window (s); None: the family's ``default_fit_window``.
    dt : float or None
        The model step (s); None: the family's ``DEFAULT_DT``.
    max_nfev : int
        Least-squares iterations of each fit.
    equation_error_seed : bool
        Start from the model's equation-error estimate (``model.seed``; ships) when it
        simulates better than the nominal coefficients.
    weighting : str or None
        ``"noise"`` or ``"residual"`` channel weights
        (:func:`bayesid.estimation.windows.fit_weighted`); None: the family's default.
    channels : tuple of str or None
        The scored channels (None: every one the tracks measure).
    start : str
        The window start-state rule (:data:`bayesid.protocol.START_RULES`).
    starts : int
        Extra Latin-hypercube starts of a multistart fit (0: the default start alone).
    random_seed : int
        Seed of the multistart starts.
    prior : bool
        Use the vehicle file's ``[prior]`` section when it has one (a MAP fit).
    """

    free: tuple | None = None
    effects: tuple = ()
    window_s: float | None = None
    dt: float | None = None
    max_nfev: int = 60
    equation_error_seed: bool = True
    weighting: str | None = None
    channels: tuple | None = None
    start: str = "auto"
    starts: int = 0
    random_seed: int = 0
    prior: bool = True

    def __post_init__(self):
        for name in ("free", "effects", "channels"):
            v = getattr(self, name)
            if v is not None and not isinstance(v, tuple):
                object.__setattr__(self, name, tuple(v))
        if int(self.max_nfev) < 1:
            raise ValueError(f"FitOptions.max_nfev must be at least 1, not {self.max_nfev}")
        if int(self.starts) < 0:
            raise ValueError(f"FitOptions.starts must be 0 or more, not {self.starts}")
        for name in ("window_s", "dt"):
            v = getattr(self, name)
            if v is not None and not v > 0:
                raise ValueError(f"FitOptions.{name} must be positive, not {v}")

    def to_dict(self) -> dict:
        """The options as a JSON-able dict (a run's identity)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}


@dataclass(frozen=True)
class CalibrationOptions:
    """How a fit calibrates its predictive bands leave one run out
    (:func:`bayesid.estimation.calibration.leave_one_run_out`).

    Attributes
    ----------
    window_s : float
        The protocol window of the window scores (s): the bands hold for windows of this length.
    draws : int
        Posterior draws of each fold for the index spreads (at least 3).
    seed : int
        Seed of those draws (fold ``g`` uses ``seed + g``).
    max_folds : int
        With more runs than this, run ``i`` is left out in fold ``i % max_folds``.
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
        """The options as a JSON-able dict (a run's identity)."""
        return asdict(self)
