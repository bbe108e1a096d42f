"""The paper's identification cases (Furlong et al. 2003, Sec. 4), seeded and reproducible.

* Case 1: every X, Y, N coefficient of the horizontal-plane model is unknown; starts drawn
  uniformly within +-10 % of the true values; bounds +-10 % of the *starting* value.
* Case 2: the coefficients a towing tank gives without a planar motion mechanism ("static": those
  of u, v, the control angles and propulsion) are known; the rotary and added-mass ones are
  identified; starts within +-10 %; bounds +-25 % of the *true* value.
* Case 3: Case 2 with each known coefficient perturbed by up to +-1 % (uniform).

Coefficients whose true value is zero cannot be scaled as a ratio and are never free (the paper's
"crosses": zero or known). The categories come from the term library
(:attr:`bayesid.data.terms.Term.category`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .data import terms


@dataclass
class Case:
    """Setup of one identification case (all values prime).

    Parameters
    ----------
    name : str
        ``"case1"``, ``"case2"`` or ``"case3"``.
    description : str
        The case in words.
    free : list of str
        Names identified.
    known : list of str
        Horizontal-plane names held fixed (non-zero truth).
    true : dict
        ``{name: true value}`` (all horizontal-plane terms).
    start : dict
        ``{free name: starting value}`` (also the ratio-scaling reference).
    lower, upper : dict
        ``{free name: bound value}``.
    known_values : dict
        ``{known name: value used}`` (perturbed in Case 3).
    """

    name: str
    description: str
    free: list
    known: list
    true: dict
    start: dict
    lower: dict
    upper: dict
    known_values: dict

    def reference(self) -> np.ndarray:
        """Scaling reference: the starting values.

        Returns
        -------
        ndarray, shape (P,)
            The starting values of the free coefficients.
        """
        return np.array([self.start[n] for n in self.free])

    def scaled_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds on p = theta / start.

        Returns
        -------
        lo, hi : ndarray, shape (P,)
            Lower and upper bounds.
        """
        ref = self.reference()
        a = np.array([self.lower[n] for n in self.free]) / ref
        b = np.array([self.upper[n] for n in self.free]) / ref
        return np.minimum(a, b), np.maximum(a, b)

    def true_outside_bounds(self) -> list:
        """Free coefficients whose true value lies outside their bounds (possible in Case 1,
        where bounds are +-10 % of a start that is itself up to 10 % off).

        Returns
        -------
        list of str
            The names.
        """
        out = []
        for n in self.free:
            lo, hi = sorted((self.lower[n], self.upper[n]))
            if not lo <= self.true[n] <= hi:
                out.append(n)
        return out

    def vehicle(self, vehicle):
        """The vehicle with the case's known values (identity except in Case 3).

        Parameters
        ----------
        vehicle : Vehicle
            The true vehicle.

        Returns
        -------
        Vehicle
            A copy with the known values.
        """
        return vehicle.with_coefficients(self.known_values)


def horizontal_coefficients(vehicle) -> list[str]:
    """X, Y, N terms of the horizontal-plane model with non-zero value, table order.

    Parameters
    ----------
    vehicle : Vehicle
        The vehicle.

    Returns
    -------
    list of str
        The names.
    """
    return [n for n in terms.names_where(horizontal=True) if vehicle.coefficients.get(n, 0.0) != 0.0]


def make_case(
    number: int, vehicle, rng: np.random.Generator, start_spread: float = 0.10, known_error: float = 0.01
) -> Case:
    """Build Case 1, 2 or 3 for a vehicle.

    Parameters
    ----------
    number : {1, 2, 3}
        The case.
    vehicle : Vehicle
        The true vehicle.
    rng : numpy.random.Generator
        Draws the starts (and the Case 3 perturbations).
    start_spread : float, default 0.10
        Starts lie within +- this fraction of the truth.
    known_error : float, default 0.01
        Case 3: known values perturbed within +- this fraction.

    Returns
    -------
    Case
        The case.

    Raises
    ------
    ValueError
        For a case number other than 1, 2, 3.
    """
    names = horizontal_coefficients(vehicle)
    true = {n: vehicle.coefficients[n] for n in names}
    if number == 1:
        free = names
    elif number in (2, 3):
        free = [n for n in names if terms.term(n).category != "static"]
    else:
        raise ValueError(f"case must be 1, 2 or 3, not {number}")
    known = [n for n in names if n not in free]
    start = {n: true[n] * (1.0 + rng.uniform(-start_spread, start_spread)) for n in free}
    if number == 1:
        lower = {n: start[n] * 0.9 for n in free}
        upper = {n: start[n] * 1.1 for n in free}
        desc = (
            "All horizontal-plane X, Y, N coefficients unknown; start within +-10 % of truth; "
            "bounds +-10 % of the start."
        )
    else:
        lower = {n: true[n] * 0.75 for n in free}
        upper = {n: true[n] * 1.25 for n in free}
        desc = (
            "Static (towing-tank) coefficients known; rotary and added-mass coefficients identified; "
            "start within +-10 % of truth; bounds +-25 % of truth."
        )
    known_values = {n: true[n] for n in known}
    if number == 3:
        known_values = {n: true[n] * (1.0 + rng.uniform(-known_error, known_error)) for n in known}
        desc += f" Known coefficients perturbed uniformly within +-{100 * known_error:g} %."
    return Case(f"case{number}", desc, list(free), known, true, start, lower, upper, known_values)
