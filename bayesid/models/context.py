"""The track context: what a model needs of one track to simulate it over the window protocol.

:class:`TrackContext` lays a track on the model's step grid: the continuous pieces between gaps
(:func:`bayesid.data.track.continuous_pieces`), the protocol windows and their start states, the scored samples (and
under the fitted start rule the samples that estimate the starts), and the logged inputs averaged
over each step, delayed and passed through a servo by the input effects. Both model families use
it (:class:`bayesid.models.submarine.EffectModel`, :class:`bayesid.models.ship.ShipModel`), and
the fits read a simulation against it: :func:`start_states` (the window-start states with the
fitted offsets), :func:`sample_rows` (the states at the samples) and :func:`errors` (prediction
minus measurement per channel).
"""

from __future__ import annotations

import copy
import math

import numba as nb
import numpy as np

from ..data.track import INPUT_NAMES, STATE_NAMES, Track, continuous_pieces
from ..protocol import CHANNELS, estimate_noise, state_at, state_guess, window_starts, wrap
from .effects import Effect

# ---------------------------------------------------------------------------------------------
# Input processing
# ---------------------------------------------------------------------------------------------
#: How the logged inputs are reconstructed between their samples: ``"hold"`` keeps each sample
#: until the next (zero-order hold, the default); ``"linear"`` interpolates linearly between
#: samples, as a rate-limited rudder logged at its instantaneous angle moves (issue 50: a
#: 16 deg/s rudder held over a 0.2 s log interval acts half a sample late on average);
#: ``"rate"`` moves the control surfaces at the steering gear's rate between samples
#: (:func:`rate_limited_knots`; the propeller linearly).
INPUT_RECONSTRUCTIONS = ("hold", "linear", "rate")


def rate_limited_knots(t, u, rate: float, lone_at: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The knots of a control surface that moves at its gear's rate between its logged samples.

    A steering gear holds its angle or moves at its rate toward the order. Between two samples
    that differ by less than the rate can move in the interval, the surface held part of it and
    moved the rest; where it did so follows from the neighbours: consecutive intervals that move
    the same way are one movement, so the first of them holds then moves (the ramp ends at its
    second sample), the last moves then holds, the ones between move all along, and a movement
    within one interval sits in its middle (the order's time is unknown there: the middle halves
    the worst timing error). An interval that moves at least as far as the rate allows, or a
    movement of several intervals whose inner one moved less (the gear paused), is kept linear.
    A ramp across samples logged at its instantaneous angle is reconstructed exactly; a linear
    interpolation cuts its corners by up to half an interval (issue 50).

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times, s, increasing.
    u : ndarray, shape (n,)
        The logged angles, rad (no missing values).
    rate : float
        The gear's rate, rad/s, positive.
    lone_at : dict, optional
        ``{interval i: fraction}``: where a movement within the interval ``t[i]..t[i + 1]``
        starts, as a fraction in [0, 1] of the time the gear held in it (0: at ``t[i]``, 1: it
        ends at ``t[i + 1]``; default 0.5, the middle). The times of such movements
        estimated with the model (:func:`lone_moves`, :meth:`TrackContext.retime`).

    Returns
    -------
    tk : ndarray, shape (m,)
        Knot times, s: the samples and the corners between them (m >= n).
    uk : ndarray, shape (m,)
        The angle at the knots, rad; linear between them.

    Raises
    ------
    ValueError
        A rate that is not positive and finite.
    """
    if not (np.isfinite(rate) and rate > 0):
        raise ValueError(f"the rudder's rate must be positive and finite, not {rate!r} rad/s")
    t, u = np.asarray(t, float), np.asarray(u, float)
    d, h = np.diff(u), np.diff(t)
    tau = np.abs(d) / rate  # how long the gear moved in each interval
    moves = np.abs(d) > 1e-9
    full = tau >= h * (1.0 - 1e-6)
    tk, uk = [t[:1]], [u[:1]]
    for i in range(d.size):
        same_before = i > 0 and moves[i - 1] and np.sign(d[i - 1]) == np.sign(d[i])
        same_after = i + 1 < d.size and moves[i + 1] and np.sign(d[i + 1]) == np.sign(d[i])
        if moves[i] and not full[i] and not (same_before and same_after):
            if same_before:  # the movement goes on from the last interval: it ends inside this one
                tk.append([t[i] + tau[i]])
                uk.append([u[i + 1]])
            elif same_after:  # it starts inside this one and goes on
                tk.append([t[i + 1] - tau[i]])
                uk.append([u[i]])
            else:  # a movement within this interval
                f = 0.5 if not lone_at else min(max(float(lone_at.get(i, 0.5)), 0.0), 1.0)
                start = t[i] + f * (h[i] - tau[i])
                tk.append([start, start + tau[i]])
                uk.append([u[i], u[i + 1]])
        tk.append(t[i + 1 : i + 2])
        uk.append(u[i + 1 : i + 2])
    return np.concatenate(tk), np.concatenate(uk)


def lone_moves(t, u, rate: float, min_step: float = 0.0) -> np.ndarray:
    """The intervals in which a control surface moved within the interval alone (neither
    movement goes on from the one before nor into the one after, and the gear had time to spare):
    the movements whose time :func:`rate_limited_knots` does not know and puts mid-interval.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times, s.
    u : ndarray, shape (n,)
        The logged angles, rad (no missing values).
    rate : float
        The gear's rate, rad/s, positive.
    min_step : float, default 0.0
        Only movements larger than this, rad.

    Returns
    -------
    ndarray of int
        The intervals ``i`` (between ``t[i]`` and ``t[i + 1]``).
    """
    t, u = np.asarray(t, float), np.asarray(u, float)
    d, h = np.diff(u), np.diff(t)
    moves = np.abs(d) > max(1e-9, min_step)
    tiny = np.abs(d) <= 1e-9
    sgn = np.sign(d)
    before = np.concatenate([[False], ~tiny[:-1] & (sgn[:-1] == sgn[1:])])
    after = np.concatenate([~tiny[1:] & (sgn[1:] == sgn[:-1]), [False]])
    return np.flatnonzero(moves & (np.abs(d) / rate < h * (1.0 - 1e-6)) & ~before & ~after)


@nb.njit(cache=True)
def _servo(x, dt, lag, rate):
    """First-order lag behind a rate limit, in place on commands sampled every ``dt``.
    The surface starts at the first command.

    Parameters
    ----------
    x : ndarray, shape (B, n)
        Commands, rad; replaced by the surface angles.
    dt : float
        Sample interval, s.
    lag : ndarray, shape (B,)
        Time constant of the lag, s (<= 1e-9: none).
    rate : ndarray, shape (B,)
        Rate limit, rad/s (<= 0: none).
    """
    B, n = x.shape
    for b in range(B):
        y = x[b, 0]
        a = math.exp(-dt / lag[b]) if lag[b] > 1e-9 else 0.0
        step = rate[b] * dt
        for k in range(n):
            target = y + (x[b, k] - y) * (1.0 - a)
            d = target - y
            if step > 0.0:
                d = min(max(d, -step), step)
            y += d
            x[b, k] = y


#: Longest model step grid a track context builds (a track's span over the model step): about
#: 6 days at 0.5 s. The grid covers the gaps between a track's pieces too, so a clock jump of
#: 1e9 s would otherwise allocate gigabytes; such a track is refused with the gap named.
MAX_GRID_STEPS = 1_000_000


class TrackContext:
    """What the model needs of one track: time grid, inputs, windows and samples.

    Window ``w`` is simulated over one *segment* of the model's step grid, from step
    ``seg_step[w]`` (``lead_steps`` before the window start under the fitted start rule with a
    lead-in, else the window start) to the next window's start. Segments may overlap (a lead-in
    lies in the previous window); the kernels see them laid end to end on a virtual step axis
    (``vmap`` maps a virtual step to the real one; None when the layout is the real grid).
    Samples scored: ``ts`` (window ``win``, output row ``row``, interpolation ``frac``, time since
    the segment start ``t_rel``, measurements ``meas``); under the fitted rule the samples that
    estimate the start are ``lead`` (same keys; the lead-in before each window start, or the
    window itself for a training fit without lead-in).

    Parameters
    ----------
    model : SimulationModel
        The model (its step ``dt`` and ``mode`` are read).
    track : Track
        The track; it needs ``x``, ``y``, ``psi``, ``delta_r`` and ``n``.
    window_s : float or None
        Protocol window, s, a whole multiple of the model step; None is one window per
        continuous piece.
    span_s : float
        Span of the measured start-state estimate, s (:func:`bayesid.protocol.state_at`); a track
        without ``u``, ``v`` or ``r`` starts its first window after ``2 * span_s``.
    s0 : array_like, shape (12,), optional
        The true state at the first sample (world generation): the start of the one window of
        the whole run, a model state.
    substeps : int, default 10
        Substeps per model step of the input servo (:meth:`average_inputs`).
    start : {"measured", "fitted"}, default "measured"
        The (resolved) start rule.
    leadin_s : float, default 0.0
        Lead-in of the fitted rule, s, a non-negative multiple of the model step and at most the
        window.
    inputs : {"hold", "linear", "rate"}, optional
        How the logged inputs are reconstructed between samples (:data:`INPUT_RECONSTRUCTIONS`);
        None: the model's ``inputs`` attribute, ``"hold"`` when it has none. Kept as
        ``input_reconstruction``. ``"rate"`` reads the gear's rate from the model's
        ``rudder_rate_deg_s`` attribute (deg/s).

    Raises
    ------
    ValueError
        An unknown start rule or input reconstruction; a track shorter than one model step, or
        spanning more than :data:`MAX_GRID_STEPS` steps (names its longest gap), or too short for
        a window after the lead-in; a window or lead-in that is not a multiple of the step; a
        lead-in longer than the window; a missing ``delta_r`` or ``n`` column or an input without
        any value; ``"rate"`` without the model's ``rudder_rate_deg_s``.
    """

    def __init__(
        self,
        model,
        track: Track,
        window_s,
        span_s,
        s0=None,
        substeps=10,
        start="measured",
        leadin_s: float = 0.0,
        inputs: str | None = None,
    ):
        dt = model.dt
        t = np.asarray(track.t, float)
        self.model, self.track, self.name = model, track, track.name
        if start not in ("measured", "fitted"):
            raise ValueError(f"start rule must be 'measured' or 'fitted' here, not {start!r}")
        inputs = getattr(model, "inputs", "hold") if inputs is None else inputs
        if inputs not in INPUT_RECONSTRUCTIONS:
            raise ValueError(f"inputs must be one of {', '.join(INPUT_RECONSTRUCTIONS)}, not {inputs!r}")
        self.input_reconstruction = inputs
        self.start = "measured" if s0 is not None else start
        self.window_s = window_s
        self.t0 = float(t[0])
        self.n_steps = int(math.floor((t[-1] - t[0]) / dt + 1e-9))
        if self.n_steps < 1:
            raise ValueError(
                f"track {track.name!r} ({t[-1] - t[0]:g} s) is shorter than one model step of {dt} s (--dt)"
            )
        if self.n_steps > MAX_GRID_STEPS:
            gaps = np.diff(t)
            i = int(np.argmax(gaps))
            raise ValueError(
                f"track {track.name!r} spans {t[-1] - t[0]:.4g} s, {self.n_steps} model steps of {dt} s "
                f"(at most {MAX_GRID_STEPS}); its longest time gap is {gaps[i]:.4g} s, from t = {t[i]:.10g} to "
                f"{t[i + 1]:.10g} s (a clock jump?): split the file at the gap, one track file per piece"
            )
        t_end = self.t0 + self.n_steps * dt
        self.t_grid = self.t0 + dt * np.arange(self.n_steps + 1)
        self.t_mid = self.t_grid[:-1] + 0.5 * dt
        if window_s is not None and abs(window_s / dt - round(window_s / dt)) > 1e-6:
            raise ValueError(
                f"window {window_s:g} s (--fit-window or --score-window) is not a whole multiple of the model step {dt:g} s (--dt)"
            )
        leadin_s = float(leadin_s) if self.start == "fitted" else 0.0
        if leadin_s < 0 or abs(leadin_s / dt - round(leadin_s / dt)) > 1e-6:
            raise ValueError(f"lead-in {leadin_s} s is not a non-negative multiple of the model step {dt} s")
        if window_s is not None and leadin_s > window_s + 1e-9:
            raise ValueError(f"lead-in {leadin_s} s is longer than the window {window_s} s")
        self.leadin_s = leadin_s
        self.lead_steps = int(round(leadin_s / dt))
        # With a velocity not measured, the causal start-state estimate needs 2*span_s of history
        # (slopes of the positions): the first window starts after it. The fitted rule starts
        # the first window after its lead-in. Windows never cross a gap in the record (a stretch
        # without x, y, psi or without samples): each continuous piece gets its own windows.
        derived = s0 is None and any(k not in track for k in ("u", "v", "r"))
        first = leadin_s if self.start == "fitted" else (2.0 * span_s if derived else 0.0)
        pieces = [(t[0], t[-1])] if s0 is not None else continuous_pieces(track, 2.0 * dt)
        steps, ends, self.skipped_pieces = [], [], 0
        for ta, tb in pieces:
            sel = (t >= ta + first - 1e-9) & (t <= min(tb, t_end) + 1e-9)
            e_piece = min(int(math.floor((tb - self.t0) / dt + 1e-9)), self.n_steps)
            st = (
                np.unique(np.round((window_starts(t[sel], window_s) - self.t0) / dt).astype(np.int64))
                if sel.any()
                else np.zeros(0, np.int64)
            )
            if st.size:  # a piece's first window starts at or after its first sample (never in the gap before it)
                st = np.unique(np.maximum(st, int(math.ceil((t[sel][0] - self.t0) / dt - 1e-6))))
            st = st[st < e_piece]
            if st.size == 0:
                self.skipped_pieces += 1
                continue
            steps.append(st)
            ends.append(np.append(st[1:], e_piece))
        if not steps:
            raise ValueError(
                f"track {track.name!r} ({t[-1] - t[0]:g} s) is too short for a window after "
                f"{first:g} s of lead-in" + (" in any of its pieces between gaps" if len(pieces) > 1 else "")
            )
        steps, ends = np.concatenate(steps), np.concatenate(ends)
        self.n_pieces = len(pieces)
        self.W = len(steps)
        self.t_start = self.t_grid[steps]
        self.t_end = self.t_grid[ends]
        self.seg_step = np.maximum(steps - self.lead_steps, 0)
        contiguous = self.lead_steps == 0 and np.array_equal(steps[1:], ends[:-1]) and ends[-1] == self.n_steps
        if contiguous:
            # the real grid (steps before the first window are simulated by no window)
            self.vmap = None
            self.starts = np.append(steps, self.n_steps).astype(np.int64)
        else:
            self.vmap = np.concatenate([np.arange(a, b) for a, b in zip(self.seg_step, ends)]).astype(np.int64)
            self.starts = np.concatenate([[0], np.cumsum(ends - self.seg_step)]).astype(np.int64)
        self._ends = ends
        self.t_seg = self.t_grid[self.seg_step]
        # the lead-in's own layout: the start fit reads only the samples before each window
        # start, so its simulations stop there (the steps before a window start do not depend on
        # the steps after it: the same states, a fraction of the work)
        self.lead_starts = None
        if self.start == "fitted" and self.lead_steps > 0:
            self._lead_vmap = np.concatenate([np.arange(a, b) for a, b in zip(self.seg_step, steps)]).astype(np.int64)
            self.lead_starts = np.concatenate([[0], np.cumsum(steps - self.seg_step)]).astype(np.int64)
        # samples scored: inside a window (from its start to its end, the next window's start
        # excluded)
        cand = np.flatnonzero(t >= self.t_start[0] - 1e-9)
        win = np.searchsorted(self.t_start, t[cand] + 1e-9, side="right") - 1
        inside = t[cand] <= self.t_end[win] + 1e-9
        self.idx = cand[inside]
        self.ts = t[self.idx]
        self.win = win[inside]
        keep = np.zeros(t.size, bool)
        keep[self.idx] = True
        self.row, self.frac = self._rows(self.ts, self.win)
        self.t_rel = self.ts - self.t_seg[self.win]
        # measured channels
        self.channels = [c for c in CHANNELS if c in track and np.isfinite(track[c][keep]).any()]
        self.meas = {c: np.asarray(track[c], float)[keep] for c in self.channels}
        # window start states: the given true initial state, the causal estimate (measured
        # rule) or the first guess at each segment start (fitted rule)
        if s0 is not None:
            self.s_meas = np.asarray(s0, float)[None, :].repeat(self.W, 0)
        elif self.start == "fitted":
            # first guess from a local fit over at least 8 samples (2 s at 4 Hz and faster): of the
            # lead-in, or of the window itself for a training fit (at 1 Hz a 2 s span holds 3
            # samples, and a fit from so bad a guess stalls at the nominal coefficients)
            h = float(np.median(np.diff(t))) if t.size > 1 else dt
            span = max(2.0, 8.0 * h) if leadin_s == 0 else min(max(2.0, 8.0 * h), max(leadin_s, 2.0))
            self.s_meas = np.array([state_guess(track, ta, span) for ta in self.t_seg])
        else:
            self.s_meas = np.array([state_at(track, ts, span_s) for ts in self.t_start])
        if model.mode == "horizontal":
            self.s_meas[:, [2, 3, 4, 8, 9, 10]] = 0.0
        self.lead = self._lead_samples(track, t) if self.start == "fitted" else None
        self._tk, self._ck, self._uk = self._input_integral(track, t, inputs, getattr(model, "rudder_rate_deg_s", None))
        self._rows = None
        self.lone_at = None
        #: Bumped when the inputs are rebuilt (:meth:`retime`): a :class:`Prepared` of before is refused.
        self.inputs_version = 0
        self.substeps = int(substeps)
        self.step_inputs = self.average_inputs(np.zeros(1))[0]
        self.row_inputs = None

    def with_row_inputs(self, tracks) -> TrackContext:
        """This context with other inputs for each parameter row: row ``b`` of a simulation reads
        the inputs of ``tracks[b]`` (reconstructed between their samples as this context reads its
        own), on this context's grid, windows and start states. One batched simulation then flies
        ``B`` input schedules (e.g. each parameter draw's own closed-loop zigzag,
        :func:`bayesid.models.runs.simulate_runs`).

        Parameters
        ----------
        tracks : sequence of Track
            One per parameter row, each with ``delta_r`` and ``n`` (only their inputs are read).

        Returns
        -------
        TrackContext
            A shallow copy whose :meth:`inputs` and :meth:`average_inputs` are per row
            (``row_inputs``, shape (B, n_steps, 4)); a simulation with it takes exactly
            ``len(tracks)`` parameter vectors.

        Raises
        ------
        ValueError
            No track, or a track without an input column or an input without any value.
        """
        if not len(tracks):
            raise ValueError("with_row_inputs needs at least one track")
        out = copy.copy(self)
        rate = getattr(self.model, "rudder_rate_deg_s", None)
        out._rows = [
            self._input_integral(tr, np.asarray(tr.t, float), self.input_reconstruction, rate) for tr in tracks
        ]
        out.row_inputs = out.average_inputs(np.zeros(len(tracks)))
        out.step_inputs = out.row_inputs[0]
        return out

    def held_inputs(self, B: int) -> np.ndarray:
        """The step inputs of ``B`` parameter rows before any input effect: the track's own
        repeated, or each row's (:meth:`with_row_inputs`).

        Parameters
        ----------
        B : int
            Number of parameter vectors.

        Returns
        -------
        ndarray, shape (B, n_steps, 4)
            A new array (the caller may change it).

        Raises
        ------
        ValueError
            Per-row inputs for another number of rows.
        """
        if self.row_inputs is None:
            return np.repeat(self.step_inputs[None], B, axis=0)
        if B != self.row_inputs.shape[0]:
            raise ValueError(f"track {self.name!r} has inputs for {self.row_inputs.shape[0]} parameter rows, not {B}")
        return self.row_inputs.copy()

    def retime(self, lone_at: dict | None) -> None:
        """Place the rudder's movements within single intervals (``inputs="rate"``) at the given
        fractions of their intervals and rebuild the step inputs (the times estimated with the
        model: :func:`bayesid.estimation.retiming.fit_retimed`).

        Parameters
        ----------
        lone_at : dict or None
            ``{interval i: fraction in [0, 1]}`` of ``delta_r`` (:func:`rate_limited_knots`);
            None: the middle of each.

        Raises
        ------
        ValueError
            A context whose inputs are not reconstructed at the gear's rate, or with per-row inputs
            (:meth:`with_row_inputs`).
        """
        if self.input_reconstruction != "rate":
            raise ValueError(f"track {self.name!r}: retiming needs inputs 'rate', not {self.input_reconstruction!r}")
        if self._rows is not None:
            raise ValueError(f"track {self.name!r}: a context with per-row inputs is not retimed")
        t = np.asarray(self.track.t, float)
        rate = self.model.rudder_rate_deg_s
        self._tk, self._ck, self._uk = self._input_integral(self.track, t, "rate", rate, lone_at)
        self.lone_at = None if lone_at is None else dict(lone_at)
        self.step_inputs = self.average_inputs(np.zeros(1))[0]
        self.inputs_version += 1

    @staticmethod
    def _input_integral(
        track: Track, t, inputs: str = "hold", rate_deg_s: float | None = None, lone_at: dict | None = None
    ) -> tuple:
        """(knot times (n + 2,), cumulative integral (n + 2, 4), input values at the knots
        (n + 2, 4) or None) of the inputs reconstructed between samples, padded beyond both ends
        with the first and last sample held: averages over any interval are exact differences of
        the integral.

        ``"hold"``: the integral is piecewise linear (the knot values alone, None for the input
        values; missing samples forward-filled). ``"linear"``: the inputs are piecewise linear
        between the knots, the integral piecewise quadratic (:func:`_linear_integral`; missing
        samples interpolated between their neighbours). ``"rate"``: as ``"linear"`` on knots that
        add the corners of the control surfaces moving at ``rate_deg_s`` (deg/s) between samples
        (:func:`rate_limited_knots`; ``lone_at`` places the rudder's movements within single
        intervals). ValueError for a missing ``delta_r`` or ``n`` column, an input without any
        value, or ``"rate"`` without a rate."""
        missing = [k for k in ("delta_r", "n") if k not in track]
        if missing:
            raise ValueError(f"track {track.name!r} has no input column(s) {missing}")
        U = track.inputs(fill=0.0)
        for j in range(4):  # fill missing samples
            col = U[:, j]
            bad = ~np.isfinite(col)
            if bad.all():
                raise ValueError(f"track {track.name!r}: input {INPUT_NAMES[j]} has no value")
            if bad.any() and inputs in ("linear", "rate"):
                col[bad] = np.interp(t[bad], t[~bad], col[~bad])
            elif bad.any():
                idx = np.where(~bad, np.arange(col.size), 0)
                np.maximum.accumulate(idx, out=idx)
                col[:] = col[idx]
                if bad[0]:
                    col[: np.argmax(~bad)] = col[np.argmax(~bad)]
        pad = 1e5
        if inputs == "rate":  # the control surfaces at the gear's rate, the propeller linear
            if rate_deg_s is None:
                raise ValueError(
                    "inputs 'rate' needs the steering gear's rate: the ship file's [service] rudder_rate_deg_s "
                    "or --rudder-rate"
                )
            rad_s = math.radians(rate_deg_s)
            knots = [rate_limited_knots(t, U[:, j], rad_s, lone_at if j == 0 else None) for j in range(3)]
            tr = np.unique(np.concatenate([t, *(k[0] for k in knots)]))
            cols = [np.interp(tr, *k) for k in knots] + [np.interp(tr, t, U[:, 3])]
            t, U = tr, np.column_stack(cols)
            inputs = "linear"
        tk = np.concatenate([[t[0] - pad], t, [t[-1] + pad]])
        dts = np.diff(t)
        if inputs == "linear":
            # trapezoids between samples (the integral is 0 at the first sample, as for the hold)
            cum = np.concatenate([[0.0 * U[0]], np.cumsum(0.5 * (U[1:] + U[:-1]) * dts[:, None], axis=0)])
            return tk, np.vstack([-U[0] * pad, cum, cum[-1] + U[-1] * pad]), np.vstack([U[:1], U, U[-1:]])
        cum = np.concatenate([[0.0 * U[0]], np.cumsum(U[:-1] * dts[:, None], axis=0)])
        return tk, np.vstack([-U[0] * pad, cum, cum[-1] + U[-1] * pad]), None

    @property
    def n_virtual(self) -> int:
        """Steps the kernels integrate (segments end to end)."""
        return int(self.starts[-1])

    def _rows(self, ts, win, starts=None):
        """(output row of the step at or before each time, fraction of the step) for samples at
        times ``ts`` simulated by windows ``win``, in the layout of ``starts`` (default the
        windows')."""
        dt = self.model.dt
        g = (ts - self.t0) / dt
        ends = self._ends
        k = np.minimum(np.floor(g + 1e-9).astype(np.int64), ends[win] - 1)
        k = np.maximum(k, self.seg_step[win])
        frac = np.clip(g - k, 0.0, 1.0)
        starts = self.starts if starts is None else starts
        return starts[win] + (k - self.seg_step[win]) + win, frac

    def _lead_samples(self, track, t):
        """Samples that estimate each window's start state under the fitted rule: the lead-in
        ``[t_seg, t_start)`` (strictly before the first scored sample), or with no lead-in the
        window's own samples (a training fit: multiple shooting proper)."""
        if self.lead_steps == 0:
            sel_t, win = self.ts, self.win
            meas = self.meas
        else:
            idx, win = [], []
            for w in range(self.W):
                i = np.flatnonzero((t >= self.t_seg[w] - 1e-9) & (t < self.t_start[w] - 1e-9))
                idx.append(i)
                win.append(np.full(i.size, w))
            idx, win = np.concatenate(idx), np.concatenate(win).astype(np.int64)
            sel_t = t[idx]
            meas = {c: np.asarray(track[c], float)[idx] for c in self.channels}
        row, frac = self._rows(sel_t, win)
        # weights of the start fit: the noise sd of each channel, from the track itself
        sd = estimate_noise(track, self.channels)
        out = {
            "ts": sel_t,
            "win": win,
            "row": row,
            "frac": frac,
            "t_rel": sel_t - self.t_seg[win],
            "meas": meas,
            "sd": sd,
        }
        if self.lead_starts is not None:  # the rows of the lead-in's own layout (:meth:`layout`)
            out["row_lead"] = self._rows(sel_t, win, self.lead_starts)[0]
        return out

    def layout(self, samples: str = "scored") -> np.ndarray:
        """Where each window's segment starts on the kernels' virtual step axis, for a
        simulation read at ``samples``: the windows' segments, or for ``"lead"`` under the fitted
        rule with a lead-in, the lead-ins alone (from the segment start to the window start).

        Parameters
        ----------
        samples : {"scored", "lead"}, default "scored"
            The samples the simulation is read at (:func:`sample_rows`).

        Returns
        -------
        ndarray, shape (W + 1,)
            Segment starts; the kernels' output has ``starts[-1] + W`` rows. Pass the same
            ``samples`` to :meth:`gather`.
        """
        return self.lead_starts if samples == "lead" and self.lead_starts is not None else self.starts

    def gather(self, a, samples: str = "scored"):
        """Lay a per-step array out on the kernels' virtual step axis (of :meth:`layout`).

        Parameters
        ----------
        a : ndarray, shape (B, n_steps, ...)
            Per-step values.
        samples : {"scored", "lead"}, default "scored"
            The samples the simulation is read at, as passed to :meth:`layout`.

        Returns
        -------
        ndarray, shape (B, n_virtual, ...)
            ``a`` itself when the layout is the real grid, else a contiguous copy.
        """
        if samples == "lead" and self.lead_starts is not None:
            return np.ascontiguousarray(a[:, self._lead_vmap])
        return a if self.vmap is None else np.ascontiguousarray(a[:, self.vmap])

    def average_inputs(self, delay, fine=False):
        """Inputs averaged over each step (or substep), delayed.

        Parameters
        ----------
        delay : ndarray, shape (B,)
            Delay of the inputs, s.
        fine : bool, default False
            Average over the substeps (``substeps`` per step) instead of the steps.

        Returns
        -------
        ndarray, shape (B, n, 4)
            The averaged inputs; n is ``n_steps`` (times ``substeps`` if ``fine``); row ``b`` of a
            context with per-row inputs (:meth:`with_row_inputs`) reads row ``b``'s.

        Raises
        ------
        ValueError
            Per-row inputs for another number of rows than ``delay`` has.
        """
        m = self.substeps if fine else 1
        tf = self.t0 + self.model.dt / m * np.arange(self.n_steps * m + 1)
        out = np.empty((delay.size, tf.size - 1, 4))
        h = self.model.dt / m
        if self._rows is not None and delay.size != len(self._rows):
            raise ValueError(f"track {self.name!r} has inputs for {len(self._rows)} parameter rows, not {delay.size}")
        for b, d in enumerate(delay):
            tk, ck, uk = (self._tk, self._ck, self._uk) if self._rows is None else self._rows[b]
            if uk is not None:
                out[b] = np.diff(_linear_integral(tf - d, tk, ck, uk), axis=0) / h
                continue
            for j in range(4):
                c = np.interp(tf - d, tk, ck[:, j])
                out[b, :, j] = np.diff(c) / h
        return out

    def inputs(self, effects, qs, B: int) -> np.ndarray:
        """Step inputs after the input effects (delay, servo, input maps).

        Parameters
        ----------
        effects : sequence of Effect
            The model's effects.
        qs : sequence of ndarray
            Their parameters, (B, n_q_e) each.
        B : int
            Number of parameter vectors.

        Returns
        -------
        ndarray, shape (B, n_steps, 4)
            The inputs per step. Rows whose input effects have the same parameters (a
            finite-difference Jacobian perturbs one parameter per row) are computed once: each row's
            inputs depend on its own parameters alone, so the result is the same to the bit.
        """
        acting = [
            i
            for i, (e, q) in enumerate(zip(effects, qs))
            if e.delay(q) is not None or e.actuator(q) is not None or type(e).input_map is not Effect.input_map
        ]
        if acting and B > 1 and self.row_inputs is None and self._rows is None:
            key = np.concatenate([np.asarray(qs[i], float).reshape(B, -1) for i in acting], axis=1)
            _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
            if first.size < B:
                sub = self.inputs(effects, [np.asarray(q)[first] for q in qs], first.size)
                return sub[np.asarray(inv).ravel()]
        delay, servo = None, None
        for e, q in zip(effects, qs):
            delay = e.delay(q) if e.delay(q) is not None else delay
            servo = e.actuator(q) if e.actuator(q) is not None else servo
        if delay is None and servo is None:
            x = self.held_inputs(B)
        elif servo is None:
            x = self.average_inputs(np.zeros(B) if delay is None else np.asarray(delay, float))
        else:
            x = self.average_inputs(np.zeros(B) if delay is None else np.asarray(delay, float), fine=True)
            m = self.substeps
            lag, rate = servo
            for j in range(3):
                col = np.ascontiguousarray(x[:, :, j])
                _servo(col, self.model.dt / m, np.asarray(lag, float), np.asarray(rate, float))
                x[:, :, j] = col
            x = x.reshape(B, self.n_steps, m, 4).mean(axis=2)
        for e, q in zip(effects, qs):
            if type(e).input_map is not Effect.input_map:
                e.input_map(x, q)
        return x


def _linear_integral(tq, tk, ck, uk) -> np.ndarray:
    """The integral of inputs linear between knots, evaluated exactly at times ``tq``.

    Parameters
    ----------
    tq : ndarray, shape (m,)
        Times, s (clipped to the knots' span).
    tk : ndarray, shape (n,)
        Knot times, s, increasing.
    ck : ndarray, shape (n, k)
        The integral at the knots.
    uk : ndarray, shape (n, k)
        The inputs at the knots.

    Returns
    -------
    ndarray, shape (m, k)
        ``ck[i] + uk[i] s + (uk[i + 1] - uk[i]) s^2 / (2 h_i)`` with ``s = tq - tk[i]`` in the knot
        interval ``i`` (of length ``h_i``) that holds ``tq``.
    """
    tq = np.clip(tq, tk[0], tk[-1])
    i = np.clip(np.searchsorted(tk, tq, side="right") - 1, 0, tk.size - 2)
    s = (tq - tk[i])[:, None]
    slope = (uk[i + 1] - uk[i]) / (tk[i + 1] - tk[i])[:, None]
    return ck[i] + uk[i] * s + 0.5 * slope * s * s


#: State components (STATE_NAMES indices x, y, psi, u, v, r) of a window start that the fitted
#: start rule estimates.
START_INDEX = np.array([0, 1, 5, 6, 7, 11])


class Prepared:
    """What a model's simulation of one track computes before its start states: the coefficient
    rows, mass matrices, inputs and exogenous forces of parameter rows ``P`` on ``ctx``
    (``model.prepare``). A start-state fit simulates the same rows on the same track from many
    start states (:func:`bayesid.estimation.shooting.fit_starts`) and prepares them once.

    Parameters
    ----------
    ctx : TrackContext
        The track.
    P : ndarray, shape (B, n_params)
        The parameter rows.
    nuisance : ndarray or None
        The track's nuisance rows.
    parts : dict
        The model's own arrays (read only by the model that made them).
    """

    __slots__ = ("ctx", "P", "nuisance", "parts", "_inputs_version")

    def __init__(self, ctx: TrackContext, P, nuisance, parts: dict):
        self.ctx, self.P, self.nuisance, self.parts = ctx, P, nuisance, parts
        self._inputs_version = ctx.inputs_version

    def check(self, ctx: TrackContext, P, nuisance) -> None:
        """Refuse a simulation this preparation is not of.

        Parameters
        ----------
        ctx : TrackContext
            The track simulated (the one prepared, its inputs not rebuilt since).
        P : array_like, shape (B, n_params)
            The parameter rows simulated.
        nuisance : array_like or None
            The nuisance rows simulated.

        Raises
        ------
        ValueError
            Another track, other rows or nuisances, or inputs rebuilt since (:meth:`TrackContext.retime`).
        """
        same_nu = (self.nuisance is None and nuisance is None) or (
            self.nuisance is not None
            and nuisance is not None
            and np.array_equal(self.nuisance, np.atleast_2d(nuisance))
        )
        if not (
            ctx is self.ctx
            and ctx.inputs_version == self._inputs_version
            and np.array_equal(np.atleast_2d(np.asarray(P, float)), self.P)
            and same_nu
        ):
            raise ValueError(
                f"track {ctx.name!r}: the simulation was prepared for another track, other parameter rows or inputs"
            )


def prepared_for(model, ctx: TrackContext, P, nuisance, prepared: Prepared | None) -> Prepared:
    """``prepared`` checked against the simulation asked for, or ``model.prepare`` of it.

    Parameters
    ----------
    model : SimulationModel
        The model, with a ``prepare`` method.
    ctx : TrackContext
        The track.
    P : array_like, shape (B, n_params)
        The parameter rows.
    nuisance : array_like or None
        The nuisance rows.
    prepared : Prepared or None
        A preparation passed to ``model.simulate``.

    Returns
    -------
    Prepared
        The preparation to simulate with.

    Raises
    ------
    ValueError
        ``prepared`` of another track, other rows or nuisances, or inputs rebuilt since.
    """
    if prepared is None:
        return model.prepare(ctx, P, nuisance)
    prepared.check(ctx, P, nuisance)
    return prepared


def start_states(ctx: TrackContext, B: int, starts=None) -> np.ndarray:
    """Window-start states of a context (measured frame) plus the fitted offsets.

    Parameters
    ----------
    ctx : TrackContext
        The prepared track.
    B : int
        Number of parameter vectors.
    starts : ndarray, shape (B, W, 6), optional
        Offsets in the :data:`START_INDEX` components.

    Returns
    -------
    ndarray, shape (B, W, 12)
        The start states, headings wrapped.
    """
    s0 = np.repeat(ctx.s_meas[None], B, axis=0)
    if starts is not None:
        s0[..., START_INDEX] += starts
        s0[..., 5] = wrap(s0[..., 5])
    return s0


def sample_rows(ctx: TrackContext, out: np.ndarray, samples: str, angles: slice):
    """States at a context's samples, linearly interpolated between the kernel's output rows
    (angles by their wrapped increment).

    Parameters
    ----------
    ctx : TrackContext
        The prepared track.
    out : ndarray, shape (B, starts[-1] + W, n_state)
        The kernel's output rows, in the layout ``starts = ctx.layout(samples)`` (for ``"lead"``
        also the windows' layout ``ctx.starts``: a model that simulates whole windows).
    samples : {"scored", "lead"}
        The scored samples or those that estimate the start states.
    angles : slice
        The angle components of the state.

    Returns
    -------
    S : ndarray, shape (B, n, n_state)
        The states at the samples.
    t_rel : ndarray, shape (n,)
        Time of each sample since its segment start, s.

    Raises
    ------
    ValueError
        For another ``samples``, or ``"lead"`` on a context without lead-in samples.
    """
    if samples == "lead":
        if ctx.lead is None:
            raise ValueError(f"track {ctx.name!r}: no lead-in samples (start rule {ctx.start!r})")
        # the lead-in's own layout (ctx.layout("lead")) or the windows' (a model that simulates whole windows)
        short = ctx.lead_starts is not None and out.shape[1] == ctx.lead_starts[-1] + ctx.W
        row, frac, t_rel = ctx.lead["row_lead" if short else "row"], ctx.lead["frac"], ctx.lead["t_rel"]
    elif samples == "scored":
        row, frac, t_rel = ctx.row, ctx.frac, ctx.t_rel
    else:
        raise ValueError(f"samples must be 'scored' or 'lead', not {samples!r}")
    a = out[:, row]
    b = out[:, np.minimum(row + 1, out.shape[1] - 1)]
    f = frac[None, :, None]
    ang = a[..., angles] + f * wrap(b[..., angles] - a[..., angles])
    # S = (1 - f) a + f b, in place (a and b are copies): two arrays of the output's size
    a *= 1.0 - f
    b *= f
    a += b
    del b
    a[..., angles] = ang
    return a, t_rel


def errors(ctx: TrackContext, S: np.ndarray, samples: str = "scored") -> dict:
    """Prediction minus measurement per scored channel.

    Parameters
    ----------
    ctx : TrackContext
        The prepared track.
    S : ndarray, shape (B, n, 12)
        Predicted states at the samples (:func:`sample_rows`).
    samples : {"scored", "lead"}, default "scored"
        The scored samples or those that estimate the start states.

    Returns
    -------
    dict
        ``{channel: (B, n) errors}``, psi wrapped.
    """
    out = {}
    meas = ctx.lead["meas"] if samples == "lead" else ctx.meas
    for c in ctx.channels:
        i = STATE_NAMES.index(c)
        e = S[..., i] - meas[c][None, :]
        out[c] = wrap(e) if c == "psi" else e
    return out


__all__ = [
    "TrackContext",
    "Prepared",
    "prepared_for",
    "INPUT_RECONSTRUCTIONS",
    "lone_moves",
    "rate_limited_knots",
    "MAX_GRID_STEPS",
    "errors",
    "START_INDEX",
    "start_states",
    "sample_rows",
]
