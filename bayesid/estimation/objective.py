"""Whole-track output-error objective: the simulated track against a target track.

The paper's Section 3 (Furlong et al. 2003): cost

    V(p) = sum_i sum_{c in x, y, z, phi, theta, psi} (c_target(t_i) - c_sim(t_i; p))**2    (paper Eq. 6)

over bounded parameters scaled as ratios to a reference value, ``p_j = theta_j / theta_ref_j``,
minimised by :func:`bayesid.estimation.fit.fit` (SLSQP, the paper's SQP, or trust-region
reflective least squares on the residual vector). The finite-difference Jacobian is *one*
batched simulation of P + 1 tracks. The whole track is simulated from the known start state with
the manoeuvre's own inputs (closed-loop zigzags included); the windowed objective of real runs is
:class:`bayesid.estimation.windows.WindowObjective`.

Units: position residuals in metres and angle residuals in radians are summed as they are,
exactly as the paper's V(p) does.
"""

from __future__ import annotations

import numpy as np

from ..data.track import STATE_NAMES, Track
from ..models.simulate import Simulator

PAPER_CHANNELS = ("x", "y", "z", "phi", "theta", "psi")
#: Residual assigned to every sample of a diverged track, so optimisers see a large finite value
#: (SLSQP and least_squares cannot handle inf/NaN); the honest cost is +inf (see ``cost_batch``).
DIVERGED_RESIDUAL = 1e6


class Problem:
    """One identification problem: simulator with free coefficients, target track, scaling.

    Parameters
    ----------
    simulator : Simulator
        The :class:`~bayesid.models.simulate.Simulator` whose ``free`` names are identified.
    target : Track
        The :class:`~bayesid.data.track.Track` whose times lie on the simulator's sample grid.
    reference : array_like, shape (P,)
        Non-zero prime values; the optimiser works on ``p = theta / reference``.
    channels : sequence of str, default PAPER_CHANNELS
        State columns compared (the paper's six; absent ones are skipped).
    fd_step : float, default 1e-7
        Forward-difference step in scaled units.

    Raises
    ------
    ValueError
        A reference of another shape, a reference value that is zero or non-finite (a ratio
        cannot be formed); target times off the simulation grid; no channel in common.
    """

    def __init__(self, simulator: Simulator, target: Track, reference, channels=PAPER_CHANNELS, fd_step: float = 1e-7):
        self.sim = simulator
        self.names = list(simulator.free)
        ref = np.asarray(reference, dtype=float)
        if ref.shape != (len(self.names),):
            raise ValueError(f"reference has shape {ref.shape}, expected ({len(self.names)},)")
        for n, r in zip(self.names, ref):
            if not np.isfinite(r) or r == 0.0:
                raise ValueError(f"coefficient {n}: reference value {r} cannot scale a ratio")
        self.reference = ref
        self.channels = [c for c in channels if c in target]
        if not self.channels:
            raise ValueError(f"target track {target.name!r} has none of the channels {channels}")
        self.ch_idx = np.array([STATE_NAMES.index(c) for c in self.channels])
        pos = (target.t - simulator.t[0]) / (simulator.t[1] - simulator.t[0])
        idx = np.round(pos).astype(int)
        if np.any(np.abs(pos - idx) > 1e-6) or idx.min() < 0 or idx.max() >= simulator.n_samples:
            raise ValueError(
                f"target track {target.name!r}: sample times are not on the simulation grid "
                f"(dt_sample = {simulator.t[1] - simulator.t[0]:g} s, span {simulator.t[-1]:g} s)"
            )
        self.t_idx = idx
        self.y = np.column_stack([target[c] for c in self.channels])  # (n, C)
        self.mask = np.isfinite(self.y)
        self.y0 = np.where(self.mask, self.y, 0.0)
        self.fd_step = fd_step
        self.n_residuals = self.y.size

    # -- the objective protocol of bayesid.estimation.fit ----------------------------------------
    #: residuals are a pure function of p (the fit may reuse them)
    cache_residuals = True

    @property
    def n_simulations(self) -> int:
        """Tracks simulated so far."""
        return self.sim.n_tracks

    @property
    def sim_seconds(self) -> float:
        """Wall time inside the batched simulator so far (s)."""
        return self.sim.sim_seconds

    def residuals(self, p) -> tuple[np.ndarray, bool]:
        """Residuals at one scaled vector and whether it diverged.

        Parameters
        ----------
        p : array_like, shape (n_free,)
            Scaled parameters.

        Returns
        -------
        r : ndarray, shape (n_residuals,)
            The residuals.
        diverged : bool
            Whether the simulation diverged.
        """
        R, div = self.residuals_batch(np.asarray(p, dtype=float)[None])
        return R[0], bool(div[0])

    def result_fields(self, p) -> dict:
        """The fit result's fields at ``p``.

        Parameters
        ----------
        p : array_like, shape (n_free,)
            Scaled parameters.

        Returns
        -------
        dict
            ``p`` (scaled) and ``theta`` (prime).
        """
        return {"p": np.asarray(p, dtype=float), "theta": self.theta(p)}

    def noise_vector(self, sigmas: dict) -> np.ndarray:
        """Per-residual noise standard deviation from per-channel values.

        Parameters
        ----------
        sigmas : dict
            ``{channel: sd}``, SI.

        Returns
        -------
        ndarray, shape (n_residuals,)
            The sd of each residual.

        Raises
        ------
        KeyError
            Naming a channel without one.
        """
        missing = [c for c in self.channels if c not in sigmas]
        if missing:
            raise KeyError(f"no noise standard deviation for channel(s) {missing}")
        per = np.array([float(sigmas[c]) for c in self.channels])
        return np.tile(per, self.y.shape[0])

    # -- scaled <-> prime ----------------------------------------------------------------------
    def theta(self, p) -> np.ndarray:
        """Prime coefficients from scaled parameters.

        Parameters
        ----------
        p : array_like, shape (..., n_free)
            Scaled parameters.

        Returns
        -------
        ndarray
            Prime coefficients, same shape as ``p``.
        """
        return np.asarray(p, dtype=float) * self.reference

    def scaled(self, theta) -> np.ndarray:
        """Scaled parameters from prime coefficients.

        Parameters
        ----------
        theta : array_like, shape (..., n_free)
            Prime coefficients.

        Returns
        -------
        ndarray
            ``theta / reference``, same shape as ``theta``.
        """
        return np.asarray(theta, dtype=float) / self.reference

    # -- batched evaluations -------------------------------------------------------------------
    def residuals_batch(self, P) -> tuple[np.ndarray, np.ndarray]:
        """Residuals (target - simulated) for B parameter vectors in one batched simulation.

        Parameters
        ----------
        P : array_like, shape (B, n_free)
            Scaled parameters.

        Returns
        -------
        R : ndarray, shape (B, n_residuals)
            Sample-major; zero where the target is missing.
        diverged : ndarray of bool, shape (B,)
            Diverged rows hold ``DIVERGED_RESIDUAL``.
        """
        P = np.atleast_2d(P)
        res = self.sim.run(self.theta(P))
        S = res.states[:, self.t_idx][:, :, self.ch_idx]  # (B, n, C)
        R = np.where(self.mask[None], self.y0[None] - S, 0.0)
        div = res.diverged | ~np.isfinite(R).all(axis=(1, 2))
        R[div] = DIVERGED_RESIDUAL
        return R.reshape(R.shape[0], -1), div

    def cost_batch(self, P) -> np.ndarray:
        """V(p) for B parameter vectors.

        Parameters
        ----------
        P : array_like, shape (B, n_free)
            Scaled parameters.

        Returns
        -------
        ndarray, shape (B,)
            The costs; ``+inf`` for a diverged simulation.
        """
        R, div = self.residuals_batch(P)
        V = np.einsum("ij,ij->i", R, R)
        V[div] = np.inf
        return V

    def cost(self, p) -> float:
        """V(p) at one scaled vector.

        Parameters
        ----------
        p : array_like, shape (n_free,)
            Scaled parameters.

        Returns
        -------
        float
            The cost; ``+inf`` for a diverged simulation.
        """
        return float(self.cost_batch(np.asarray(p)[None])[0])

    def jacobian(self, p, r0=None, central: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Residuals at p and their finite-difference Jacobian d r / d p, from ONE batched
        simulation of P + 1 tracks (P if ``r0``, the residuals at p, is given; 2P + 1 for
        ``central`` differences, whose O(h^2) error suits identifiability analysis).

        Parameters
        ----------
        p : array_like, shape (P,)
            Scaled parameters.
        r0 : ndarray, shape (n_residuals,), optional
            The residuals at ``p`` when known (forward differences only).
        central : bool, default False
            Central differences (step 1e-5 in scaled units) instead of forward ones.

        Returns
        -------
        r : ndarray, shape (n_residuals,)
            The residuals at ``p``.
        J : ndarray, shape (n_residuals, P)
            The Jacobian.
        """
        p = np.asarray(p, dtype=float)
        P_ = p.size
        h = self.fd_step * np.maximum(1.0, np.abs(p))
        if central:
            h = 1e-5 * np.maximum(1.0, np.abs(p))  # truncation O(h^2) ~ 1e-10, round-off ~ 1e-11
            batch = np.vstack(
                [p[None], np.repeat(p[None], P_, axis=0) + np.diag(h), np.repeat(p[None], P_, axis=0) - np.diag(h)]
            )
            R, _ = self.residuals_batch(batch)
            return R[0], ((R[1 : P_ + 1] - R[P_ + 1 :]) / (2 * h)[:, None]).T
        batch = np.repeat(p[None], P_, axis=0) + np.diag(h)
        if r0 is None:
            R, _ = self.residuals_batch(np.vstack([p[None], batch]))
            r0, Rp = R[0], R[1:]
        else:
            Rp, _ = self.residuals_batch(batch)
        return r0, ((Rp - r0[None]) / h[:, None]).T

    def gradient(self, p, r0=None) -> tuple[float, np.ndarray]:
        """Cost and gradient ``dV/dp = 2 J^T r`` (J = d r / d p) -- differencing the residuals
        avoids the cancellation of differencing V itself. One batched call.

        Parameters
        ----------
        p : array_like, shape (P,)
            Scaled parameters.
        r0 : ndarray, shape (n_residuals,), optional
            The residuals at ``p`` when known.

        Returns
        -------
        cost : float
            V(p).
        gradient : ndarray, shape (P,)
            dV/dp.
        """
        r, J = self.jacobian(p, r0)
        return float(r @ r), 2.0 * (J.T @ r)


class _SimGroup:
    """Work counters summed over the simulators of a :class:`JointProblem`."""

    def __init__(self, sims):
        self.sims = list(sims)

    @property
    def sim_seconds(self) -> float:
        return sum(s.sim_seconds for s in self.sims)

    @property
    def n_tracks(self) -> int:
        return sum(s.n_tracks for s in self.sims)


class JointProblem(Problem):
    """Several manoeuvres identified together: one coefficient vector, residuals stacked.

    The cost is the sum of the members' costs (paper Eq. 6 summed over manoeuvres), so
    combining manoeuvres is identification on all their samples at once. Every method of
    :class:`Problem` (cost, batched Jacobian, gradient) works unchanged; one batched evaluation
    runs one batched simulation per member.

    Parameters
    ----------
    problems : list of Problem
        Members with the same free names, reference and channels.

    Raises
    ------
    ValueError
        Empty list, or members differing in free names, reference or channels (named).
    """

    def __init__(self, problems):
        problems = list(problems)
        if not problems:
            raise ValueError("JointProblem needs at least one problem")
        first = problems[0]
        for k, p in enumerate(problems[1:], 1):
            for what in ("names", "channels"):
                if list(getattr(p, what)) != list(getattr(first, what)):
                    raise ValueError(
                        f"problem {k} ({p.sim.manoeuvre.name}): {what} {getattr(p, what)} "
                        f"differ from {getattr(first, what)}"
                    )
            if not np.array_equal(p.reference, first.reference):
                raise ValueError(f"problem {k} ({p.sim.manoeuvre.name}): reference values differ")
        self.problems = problems
        self.names, self.reference, self.channels = first.names, first.reference, first.channels
        self.y = np.vstack([p.y for p in problems])
        self.mask = np.vstack([p.mask for p in problems])
        self.y0 = np.where(self.mask, self.y, 0.0)
        self.fd_step = first.fd_step
        self.n_residuals = self.y.size
        self.sim = _SimGroup(p.sim for p in problems)

    def residuals_batch(self, P) -> tuple[np.ndarray, np.ndarray]:
        """Stacked residuals of the members for B parameter vectors.

        Parameters
        ----------
        P : array_like, shape (B, n_free)
            Scaled parameters.

        Returns
        -------
        R : ndarray, shape (B, sum of the members' n_residuals)
            The residuals; diverged rows hold ``DIVERGED_RESIDUAL``.
        diverged : ndarray of bool, shape (B,)
            Whether any member diverged.
        """
        parts = [p.residuals_batch(P) for p in self.problems]
        R = np.hstack([r for r, _ in parts])
        div = np.any(np.vstack([d for _, d in parts]), axis=0)
        R[div] = DIVERGED_RESIDUAL
        return R, div


__all__ = ["Problem", "JointProblem", "PAPER_CHANNELS", "DIVERGED_RESIDUAL"]
