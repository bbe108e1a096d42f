"""The synthetic world of the withheld-effect benchmark: "measured" tracks of a vehicle flying a
manoeuvre with effects of the catalogue switched on (:func:`world_track`), at the benchmark's
effect magnitudes (:func:`draw_parameters`) and navigation noise (:data:`WORLD_NOISE`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..data.track import INPUT_NAMES, STATE_NAMES, Track
from ..protocol import wrap
from .effects import Effect, get
from .simulate import Manoeuvre
from .submarine import EffectModel

#: Realistic measurement noise of the withheld-effect benchmark (1 sd): RTK-GPS/USBL-aided
#: navigation, gyro compass, DVL, rate gyros, depth cell, inclinometers.
WORLD_NOISE = {
    "x": 0.2,
    "y": 0.2,
    "z": 0.05,
    "phi": math.radians(0.1),
    "theta": math.radians(0.1),
    "psi": math.radians(0.2),
    "u": 0.02,
    "v": 0.02,
    "w": 0.02,
    "p": math.radians(0.1),
    "q": math.radians(0.1),
    "r": math.radians(0.1),
}


@dataclass(frozen=True)
class LogOptions:
    """How a world track is logged (:func:`world_track`).

    Parameters
    ----------
    noise : dict, optional
        ``{channel: sd}`` (SI; default :data:`WORLD_NOISE`); every state is recorded.
    sample_every : int, default 1
        Record every k-th integration step (1: a 10 Hz log at the manoeuvre's 0.1 s step; the
        inputs are logged at the same rate, and a coarser log misplaces every rudder step by up
        to one sample interval).
    hold_inputs : bool, default False
        The vehicle is driven by the logged inputs: each command is held over its log interval
        (an autopilot that runs at the log rate), so a coarse log records the inputs exactly.
        Without it a 5 Hz log of a 10 Hz zigzag misplaces each rudder reversal by up to 0.1 s,
        which alone costs the true model 0.4-1 m over 60 s windows.
    """

    noise: dict | None = None
    sample_every: int = 1
    hold_inputs: bool = False


def draw_parameters(name: str, level: int, rng: np.random.Generator) -> dict:
    """Parameters of an effect at a benchmark level (:attr:`~bayesid.models.effects.Effect.magnitudes`).

    The current's direction (towards, from north) is drawn uniformly from ``rng``; draw once per
    case and pass the result to every :func:`world_track` of that case.

    Parameters
    ----------
    name : str
        Catalogue name of the effect.
    level : {0, 1, 2}
        Benchmark level.
    rng : numpy.random.Generator
        Draws the current's direction.

    Returns
    -------
    dict
        ``{param: value}`` (a current as north and east components, m/s).
    """
    e = get(name)
    pv = dict(e.magnitudes[level])
    if name == "current":
        sp = pv.pop("speed_mps")
        dr = float(rng.uniform(0.0, 2.0 * math.pi))
        pv = {"current_north_mps": sp * math.cos(dr), "current_east_mps": sp * math.sin(dr)}
    return pv


def world_track(
    vehicle,
    manoeuvre: Manoeuvre,
    effects: dict,
    rng: np.random.Generator,
    log: LogOptions = LogOptions(),
    *,
    dt: float | None = None,
    nuisance=None,
    name: str | None = None,
) -> Track:
    """A "measured" track of the vehicle flying ``manoeuvre`` with ``effects`` switched on.

    Parameters
    ----------
    vehicle : Vehicle
        The true vehicle (its coefficients are the truth).
    manoeuvre : Manoeuvre
        Inputs on its grid (the logged commands) and the true initial state.
    effects : dict
        ``{effect name or Effect: {param: value}}`` (missing parameters take their ``start``
        value; see :func:`draw_parameters` for the benchmark levels; an
        :class:`~bayesid.models.effects.Effect` object outside the catalogue makes a world that
        no candidate models).
    rng : numpy.random.Generator
        All randomness (noise; wave phase and current direction if not given).
    log : LogOptions, default LogOptions()
        The navigation noise, the log's sample interval (every k-th step) and whether the
        vehicle is driven by the logged inputs.
    dt : float, optional
        Integration step, s (default the manoeuvre's).
    nuisance : array_like, optional
        Per-track parameters (default: drawn, e.g. a random phase).
    name : str, optional
        Track name; default the manoeuvre's.

    Returns
    -------
    Track
        The 12 states (noisy), the 4 logged inputs, and ``meta["truth"]`` = the effects'
        parameters (and the nuisances).

    Raises
    ------
    ValueError
        An unknown parameter of an effect.
    RuntimeError
        When the world simulation diverges.
    """
    noise, sample_every, hold_inputs = log.noise, log.sample_every, log.hold_inputs
    dt = manoeuvre.dt if dt is None else dt
    eff, qrow, truth = [], [], {}
    for en, pv in effects.items():
        e = en if isinstance(en, Effect) else get(en)
        pv = dict(pv)
        unknown = set(pv) - set(e.params)
        if unknown:
            raise ValueError(f"effect {e.name}: unknown parameter(s) {sorted(unknown)}; it has {e.params}")
        q = [float(pv.get(p, s)) for p, s in zip(e.params, e.start)]
        eff.append(e)
        qrow += q
        truth[e.name] = dict(zip(e.params, q))
    model = EffectModel(vehicle, (), eff, mode="horizontal", dt=dt)
    n = manoeuvre.n_steps
    t = manoeuvre.t
    if hold_inputs and sample_every > 1:
        U = manoeuvre.inputs[(np.arange(n) // sample_every) * sample_every]
        manoeuvre = Manoeuvre(
            manoeuvre.name, manoeuvre.dt, U, manoeuvre.initial_state, manoeuvre.description, manoeuvre.parameters
        )
    logged = Track(
        t,
        {k: np.append(manoeuvre.inputs[:, j], manoeuvre.inputs[-1, j]) for j, k in enumerate(INPUT_NAMES)},
        name=manoeuvre.name,
    )
    ctx = model.context(logged, None, s0=manoeuvre.initial_state)
    if nuisance is None:
        nuisance = rng.uniform(-math.pi, math.pi, size=max(model.n_nuisance, 1))
    if model.n_nuisance:
        truth["nuisance"] = [float(x) for x in nuisance[: model.n_nuisance]]
    S = model.simulate(ctx, np.array(qrow)[None, :], np.atleast_2d(nuisance), measured_start=False)[0]
    if not np.all(np.isfinite(S)):
        raise RuntimeError(f"world simulation of {manoeuvre.name} with {effects} diverged")
    noise = WORLD_NOISE if noise is None else noise
    keep = np.arange(0, n + 1, sample_every)
    data = {}
    for i, k in enumerate(STATE_NAMES):
        x = S[keep, i] + rng.normal(0.0, noise.get(k, 0.0), keep.size)
        data[k] = wrap(x) if k == "psi" else x
    for j, k in enumerate(INPUT_NAMES):
        data[k] = logged[k][keep]
    return Track(t[keep], data, name=name or manoeuvre.name, meta={"truth": truth})


__all__ = ["world_track", "LogOptions", "draw_parameters", "WORLD_NOISE"]
