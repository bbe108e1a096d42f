"""Plots take axes (issue 51): every figure of :mod:`bayesid.report.plots` draws onto the axes it
is given (``ax=``, or ``axes=`` for a figure of several panels) or makes them, and returns them;
it writes a PNG only when given a path (then returns the path, as the reports expect); the
posterior figures are ArviZ's; ``__all__`` lists every public function; and importing the module
leaves matplotlib's backend alone."""

from __future__ import annotations

import inspect
import json
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402

from bayesid.data.track import Track  # noqa: E402
from bayesid.models.simulate import Manoeuvre  # noqa: E402
from bayesid.report import plots  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
NAMES = ["Xvr", "Yv", "Yr", "Nv", "Nr"]
#: the figures ArviZ draws
POSTERIOR = ("walker_traces", "rank_histograms", "pair_scatter")
#: public functions of the module that are no figure of their own (they mark given axes)
NOT_FIGURES = {"mark_indices"}


def _cases() -> dict:
    """{figure: (data args, keyword args, axes shape)}: small inputs for each figure; the path
    follows the data args; shape None = one ``ax``, else the ``axes`` it draws on."""
    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 100.0, 201)
    psi = np.where(t < 10, 0.0, 0.05 * (t - 10))
    x, y = 20 * np.sin(psi) + np.where(t < 10, 0.5 * t, 5.0), 20 * (1 - np.cos(psi))
    rudder = np.where(t < 10, 0.0, -0.6)
    track = Track(t, {"x": x, "y": y, "psi": psi, "delta_r": rudder, "n": np.full(t.size, 100.0)}, name="turn")
    xy = np.c_[x, y]
    measured = {"x": x, "y": y, "psi": psi, "delta_r": rudder}
    predicted = {"x": x + 0.5, "y": y - 0.5, "psi": psi + 0.01}
    win = np.repeat([0, 1], [100, 101])
    chains = rng.normal(size=(2, 40, 4, len(NAMES)))
    samples = rng.normal(size=(400, len(NAMES)))
    inputs = np.zeros((20, 4))
    inputs[5:, 0] = 0.3
    where = {
        "channels": {"x": {"excess_ratio": 2.0}, "psi": {"excess_ratio": 1.2}},
        "regions": {
            "u": [{"bin": [0, 1], "mean_error_growth_mps": 0.1}, {"bin": [1, 2], "mean_error_growth_mps": None}],
            "r": [{"bin": [-1, 0], "mean_error_growth_mps": 0.2}],
        },
    }
    S = np.zeros((3, t.size, 12))
    S[:, :, 0], S[:, :, 1] = x, y + np.arange(3)[:, None]
    summary = {"sorted_costs": [1.0, 1.001, 1.5], "cost_tolerance": 0.01}
    summary |= {"n_near_best": 2, "n_starts": 3, "n_distinct_near_best": 1}
    alternatives = {"Nr": {"x": x, "y": y}, "without Nr": {"x": x + 1, "y": y}}
    row = SimpleNamespace(name="zigzag", separation=1.5, worst_pair=("Nr", "Yr"), predicted=alternatives)
    margin = {"mean": 1.0, "lower": 0.9, "upper": 1.1, "truth": 1.0, "prior_lo": 0.5, "prior_hi": 1.5}
    return {
        "track_xy": (({"a": track, "b": track},), {"title": "tracks"}, None),
        "inputs_time": ((track,), {}, (2,)),
        "position_error": ((t, {"a": 0.01 * t, "b": 0.02 * t}), {"title": "errors"}, (2,)),
        "coefficient_ratios": (
            (NAMES, {"Yv": 0.9, "Nr": 1.2}, {"Yv": 1.0, "Nr": 1.05}, {"Xvr": 1.0, "Yr": 1.0, "Nv": 1.0}),
            {"bounds": ({"Yv": 0.5}, {"Yv": 1.5})},
            None,
        ),
        "convergence": (({"fit": [10.0, 5.0, 2.0, 1.0]},), {}, None),
        "singular_values": (({"fit": [5.0, 2.0, 0.1]},), {}, None),
        "walker_traces": ((chains, NAMES, ["Yv", "Nr"]), {"burn": 10, "truth": {"Yv": 0.0}, "title": "T"}, (2, 2)),
        "rank_histograms": (({"Yv": rng.normal(size=(2, 100)), "Nr": rng.normal(size=(2, 100))},), {}, (2,)),
        "pair_scatter": (
            (samples, NAMES, [("Yv", "Nr"), ("Xvr", "Yr")]),
            {"truth": dict.fromkeys(NAMES, 0.0), "bounds": {"Yv": (-2, 2), "Nr": (-2, 2)}},
            (2,),
        ),
        "correlation_heatmap": ((np.corrcoef(samples, rowvar=False), NAMES), {}, None),
        "fim_spectra": (({"a": [100.0, 10.0, 1.0, 0.0]},), {"prior_level": {"a": 0.3}}, None),
        "marginals_vs_truth": (
            ([{"name": "Yv", "covers": True, **margin}, {"name": "Nr", "covers": False, **margin}],),
            {},
            None,
        ),
        "inclusion_heatmap": (({"zigzag": {"Yv": 0.9, "Nr": 0.1}, "turn": {"Yv": 0.5}},), {}, None),
        "cross_prediction": (({"a": {"a": 0.1, "b": 2.0}, "b": {"a": 1.0, "b": 0.2}},), {}, None),
        "design_inputs": (
            (
                {
                    "spiral": Manoeuvre("spiral", 0.5, inputs, np.zeros(12)),
                    "d": Manoeuvre("d", 0.5, -inputs, np.zeros(12)),
                },
            ),
            {},
            (2,),
        ),
        "predicted_vs_measured": (({"D": {"predicted_sd_ratio": 0.5, "measured_sd_ratio": 0.6}},), {}, None),
        "gap_ranking": (
            ([{"effect": "a", "heldout_rms_m": 0.4}, {"effect": "b", "heldout_rms_m": 0.5}], 0.6, 0.3),
            {"band_ratio": 1.5},
            None,
        ),
        "gap_channels": ((where,), {}, None),
        "gap_regions": ((where,), {}, (2,)),
        "window_tracks": ((xy, xy + 1.0, xy - 1.0), {"run": track}, None),
        "window_scatter": (([0.2, 0.3, 0.4], [0.1, 0.35, 0.3]), {}, None),
        "confusion_matrix": (({"a": {"a": 3, "none": 1}, "b": {"b": 2}},), {}, None),
        "turning_band": (({"a": S},), {}, None),
        "multistart": ((summary, [("optimum 1", x, y)]), {}, (2,)),
        "reliability": (
            ({"windows": {"0.5": {"coverage": 0.45, "n": 10}, "0.9": {"coverage": 0.85, "n": 10}}},),
            {"parameter_only": {"nominal": 0.9, "coverage": 0.7, "n": 10}},
            None,
        ),
        "prediction_band": (
            (measured, {**predicted, "t": t, "win": win}, {"max_position_m": 1.0, "max_heading_deg": 2.0}),
            {"title": "band"},
            (3,),
        ),
        "prior_posterior_marginals": (
            (
                samples,
                NAMES,
                {"Yv": {"kind": "normal", "mean": 0, "sd": 1}, "Nr": {"kind": "uniform", "lower": -2, "upper": 2}},
            ),
            {"mark": {"Yv": 0.1}},
            (2, 3),
        ),
        "importance_weights": ((rng.dirichlet(np.ones(50)), 0.4, 30.0), {}, None),
        "training_fit": ((t, measured, predicted, win), {}, (2,)),
        "simulated_run": ((track,), {"title": "run"}, (3,)),
        "plot_alternatives": ((row,), {}, None),
    }


CASES = _cases()


def _public_functions() -> set:
    return {
        n
        for n, obj in vars(plots).items()
        if inspect.isfunction(obj) and obj.__module__ == plots.__name__ and not n.startswith("_")
    }


def _user_axes(shape):
    """A figure the caller made, and its axes in ``shape`` (None: one Axes)."""
    if shape is None:
        return plt.subplots()
    fig, axes = plt.subplots(*(shape if len(shape) == 2 else (1, shape[0])), squeeze=False)
    return fig, axes.reshape(shape)


def _drawn(ax) -> bool:
    return ax.has_data() or bool(ax.texts) or bool(ax.images)


@pytest.fixture(autouse=True)
def _close_all():
    yield
    plt.close("all")


def test_all_lists_every_public_function():
    public = _public_functions()
    missing = public - set(plots.__all__)
    assert not missing, f"public functions of plots.py missing from __all__: {sorted(missing)}"
    assert len(plots.__all__) == len(set(plots.__all__))
    assert all(hasattr(plots, n) for n in plots.__all__)
    # every figure has a case below, so a new one is tested for taking axes too
    assert set(CASES) == public - NOT_FIGURES
    assert set(POSTERIOR) <= set(CASES)


@pytest.mark.parametrize("name", sorted(CASES))
def test_the_path_follows_the_data_and_the_axes_are_keywords(name):
    """``f(data, path, title)`` as the reports call it; ``ax``/``axes`` a keyword (no caller's
    positional argument moves)."""
    args, _, shape = CASES[name]
    params = inspect.signature(getattr(plots, name)).parameters
    kw = "ax" if shape is None else "axes"
    assert params[kw].default is None
    assert params["path"].default is None
    if name != "plot_alternatives":  # it took (row, ax) before it took a path
        assert list(params).index("path") == len(args)
        assert params[kw].kind is inspect.Parameter.KEYWORD_ONLY


@pytest.mark.parametrize("name", sorted(CASES))
def test_draws_on_the_given_axes_and_returns_them_writing_nothing(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    args, kwargs, shape = CASES[name]
    fig, made = _user_axes(shape)
    figures = plt.get_fignums()
    out = getattr(plots, name)(*args, **kwargs, **{"ax" if shape is None else "axes": made})
    assert plt.get_fignums() == figures  # no new figure, the caller's left open
    if shape is None:
        assert out is made
        assert _drawn(made)
    else:
        assert isinstance(out, np.ndarray) and out.shape == shape
        assert all(a is b for a, b in zip(out.flat, made.flat))
        assert all(_drawn(a) or not a.axison for a in out.flat)  # a grid's spare panels turned off
        assert sum(map(_drawn, out.flat)) >= out.size - 1
    assert all(a.figure is fig for a in np.ravel(out))
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("name", sorted(CASES))
def test_without_axes_draws_a_new_figure_and_returns_its_axes(name):
    args, kwargs, shape = CASES[name]
    figures = set(plt.get_fignums())
    out = getattr(plots, name)(*args, **kwargs)
    assert len(set(plt.get_fignums()) - figures) == 1
    if shape is None:
        assert isinstance(out, Axes)
    else:
        assert isinstance(out, np.ndarray) and all(isinstance(a, Axes) for a in out.flat)
        if name != "prior_posterior_marginals":  # its own grid: min(6, P) columns
            assert out.shape == shape
        assert len({a.figure for a in out.flat}) == 1


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_path_writes_the_png_and_closes_the_figure(name, tmp_path):
    args, kwargs, _ = CASES[name]
    path = tmp_path / f"{name}.png"
    figures = plt.get_fignums()
    f = getattr(plots, name)
    out = f(*args, **kwargs, path=path) if name == "plot_alternatives" else f(*args, path, **kwargs)
    assert out == path
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert plt.get_fignums() == figures


def test_given_axes_and_a_path_save_the_callers_figure_and_close_it(tmp_path):
    args, kwargs, _ = CASES["convergence"]
    fig, ax = plt.subplots()
    out = plots.convergence(*args, tmp_path / "c.png", ax=ax, **kwargs)
    assert out == tmp_path / "c.png" and out.is_file()
    assert not plt.fignum_exists(fig.number)


@pytest.mark.parametrize("name", POSTERIOR)
def test_the_posterior_figures_are_arviz(name):
    """ArviZ's figures: its panel titles (the coefficient names), and for the trace its density
    column beside the trace."""
    args, kwargs, shape = CASES[name]
    out = getattr(plots, name)(*args, **kwargs)
    if name == "walker_traces":
        assert [a.get_title() for a in out[:, 1]] == list(args[2])
        assert all(a.get_title() == b.get_title() for a, b in out)
        # one line per walker (2 ensembles x 4) after burn-in, and its burn-in joined on
        assert len(out[0, 1].lines) >= 2 * 4
    elif name == "rank_histograms":
        assert [a.get_title() for a in out] == list(args[0])
        assert all(len(a.containers) == 2 for a in out)  # a row of bars per ensemble
    else:
        assert all(a.collections for a in out)  # the hexbin
        assert out[0].get_xlabel() == "Yv" and out[0].get_ylabel() == "Nr"
        assert any(line.get_marker() == "*" for line in out[0].lines)  # the truth


def test_axes_of_another_shape_are_refused():
    args, kwargs, _ = CASES["pair_scatter"]
    _, axes = plt.subplots(1, 3)
    with pytest.raises(ValueError, match=r"pair_scatter draws on axes of shape \(2,\).*got 3"):
        plots.pair_scatter(*args, **kwargs, axes=axes)
    _, axes = plt.subplots(1, 3)
    with pytest.raises(ValueError, match="5 panels"):
        plots.prior_posterior_marginals(*CASES["prior_posterior_marginals"][0], axes=axes)


def _backend_after_import(env: dict) -> dict:
    code = (
        "import json, matplotlib\n"
        "import matplotlib.pyplot as plt\n"
        "before = matplotlib.rcParams._get_backend_or_none()\n"
        "import bayesid.report, bayesid.report.plots as plots\n"
        "chosen = matplotlib.rcParams._get_backend_or_none()\n"
        "import numpy as np\n"
        "plots.rank_histograms({'a': np.random.default_rng(0).normal(size=(2, 50))})\n"
        "print(json.dumps({'before': before, 'chosen': chosen, 'backend': matplotlib.get_backend()}))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("backend", [None, "svg"])
def test_importing_the_plots_leaves_the_backend_alone(backend):
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}
    if backend:
        env["MPLBACKEND"] = backend
    got = _backend_after_import(env)
    # nothing chose a backend on import (not even ArviZ's figures once drawn)
    assert got["chosen"] == got["before"] == backend
    if backend:
        assert got["backend"] == backend
