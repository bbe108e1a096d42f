"""bayesid: identify the hydrodynamic coefficients of manoeuvring vessels from their tracks,
with honest uncertainty.

The names a study needs are importable from the package itself (``import bayesid``;
:data:`__all__` lists them): tracks and vehicles (:class:`~bayesid.data.track.Track`,
:func:`~bayesid.data.track.read_csv`, :func:`~bayesid.data.track.write_csv`,
:func:`~bayesid.models.load_any_vehicle`, :func:`~bayesid.models.build_model`), the fit
(:func:`~bayesid.estimation.identification.identify`, :class:`~bayesid.estimation.options.FitOptions`),
the window protocol's predictions (:func:`~bayesid.estimation.prediction.predict`), the posterior
(:func:`~bayesid.estimation.track_posterior.sample_tracks`,
:class:`~bayesid.estimation.track_posterior.SampleOptions`,
:class:`~bayesid.estimation.windows.WindowProblem`), the gap diagnosis and structure discovery
(:func:`~bayesid.analysis.gap.diagnose.diagnose`, :class:`~bayesid.analysis.gap.diagnose.DiagnoseOptions`,
:func:`~bayesid.analysis.gap.discovery.discover`,
:class:`~bayesid.analysis.gap.discovery.options.DiscoveryOptions`) and :class:`~bayesid.tasks.Runner`.
Each is imported from the module that defines it at its first use, so ``import bayesid`` stays
cheap (no numba, no model module).

The layout follows the data flow; each layer imports only the ones before it (no import runs up a
layer or closes a circle; the import graph is checked):

* :mod:`bayesid.data` -- what comes in: :mod:`~bayesid.data.terms` (the term library),
  :mod:`~bayesid.data.vehicle` (vehicle files), :mod:`~bayesid.data.priors` (their ``[prior]``
  section), :mod:`~bayesid.data.track` (the Track CSV
  contract), :mod:`~bayesid.data.validate` (unit and plausibility checks),
  :mod:`~bayesid.data.datasets` (readers of real free-running data).
* :mod:`bayesid.protocol` -- the window protocol on tracks (windows, start rules, noise, pooled
  scores), which the models' track contexts use.
* :mod:`bayesid.models` -- what simulates a vessel: :mod:`~bayesid.models.interface` (the
  SimulationModel contract), :mod:`~bayesid.models.dynamics` (compiled kernels, interpreting the term table),
  :mod:`~bayesid.models.codegen` (kernels generated from the term table),
  :mod:`~bayesid.models.simulate` (Manoeuvre, Simulator), :mod:`~bayesid.models.reference`
  (solve_ivp anchor), :mod:`~bayesid.models.crossflow`, :mod:`~bayesid.models.manoeuvres`,
  :mod:`~bayesid.models.runs` (any model's manoeuvre runs: approach condition, standard menu,
  closed-loop zigzag, batched over parameter rows),
  :mod:`~bayesid.models.inverse` (smoothed motion, inverse dynamics),
  :mod:`~bayesid.models.effects` (the effect catalogue), :mod:`~bayesid.models.context` (the
  track context: windows, start states, step inputs), :mod:`~bayesid.models.submarine` (the
  submarine model and its term library), :mod:`~bayesid.models.library` (TermLibrary: the
  candidate terms a vessel family offers structure discovery), :mod:`~bayesid.models.world` (synthetic tracks with effects switched on),
  :mod:`~bayesid.models.ship` (the MMG surface ship: :mod:`~bayesid.models.ship.fileformat` the
  ship file, :mod:`~bayesid.models.ship.layout` the kernels' parameter vector,
  :mod:`~bayesid.models.ship.hullterms` extra hull terms by name,
  :mod:`~bayesid.models.ship.library` its term library,
  :mod:`~bayesid.models.ship.dynamics` the equations as interpreted kernels,
  :mod:`~bayesid.models.ship.kernel` the generated kernel, :mod:`~bayesid.models.ship.effects`
  its effects, :mod:`~bayesid.models.ship.model` the model, :mod:`~bayesid.models.ship.seed` the
  equation-error seed, :mod:`~bayesid.models.ship.trials` its standard manoeuvres).
* :mod:`bayesid.estimation` -- fitting: :mod:`~bayesid.estimation.fit` (the one fit function
  and result), :mod:`~bayesid.estimation.objective` (the paper's whole-track objective),
  :mod:`~bayesid.estimation.windows` (multiple shooting), :mod:`~bayesid.estimation.shooting`
  (fitted window starts), :mod:`~bayesid.estimation.laplace`,
  :mod:`~bayesid.estimation.posterior`, :mod:`~bayesid.estimation.sampling` (emcee, ArviZ),
  :mod:`~bayesid.estimation.options` (FitOptions, CalibrationOptions),
  :mod:`~bayesid.estimation.identification` (identification on long runs),
  :mod:`~bayesid.estimation.stepcheck` (is the model step fine enough for the data),
  :mod:`~bayesid.estimation.retiming` (when the rudder moved within a log interval),
  :mod:`~bayesid.estimation.prediction` (window protocol and whole-run predictions),
  :mod:`~bayesid.estimation.indices` (manoeuvre indices),
  :mod:`~bayesid.estimation.imo` (the IMO MSC.137(76) criteria at full scale),
  :mod:`~bayesid.estimation.modelfile` (``model.json``: ModelDocument),
  :mod:`~bayesid.estimation.multistart` (many starts of one fit),
  :mod:`~bayesid.estimation.calibration` (predictive bands calibrated leave one run out),
  :mod:`~bayesid.estimation.track_posterior` (the posterior given a user's tracks: error model,
  importance-reweighted Laplace, MCMC refinement; ``bayesid sample``).
* :mod:`bayesid.analysis` -- what the data say: :mod:`~bayesid.analysis.identifiability`,
  :mod:`~bayesid.analysis.dossier`, :mod:`~bayesid.analysis.richness`,
  :mod:`~bayesid.analysis.sindy`, :mod:`~bayesid.analysis.gap` (the gap diagnosis and
  structure discovery, :mod:`~bayesid.analysis.gap.discovery`).
* :mod:`bayesid.report` -- what goes out: :mod:`~bayesid.report.study` (study folders, JSON,
  manifests), :mod:`~bayesid.report.markdown` (tables, number format), the report writers
  :mod:`~bayesid.report.diagnosis`, :mod:`~bayesid.report.fit`, :mod:`~bayesid.report.predict`,
  :mod:`~bayesid.report.sample`, :mod:`~bayesid.report.convert`; :mod:`~bayesid.report.imo` (the
  IMO criteria table of the fit and predict reports of ships); :mod:`~bayesid.report.plots`;
  :mod:`~bayesid.report.vehiclefile` (a vehicle file with discovered terms added).
* :mod:`bayesid.cases` (the paper's Cases 1-3).
* :mod:`bayesid.cli` -- the ``bayesid`` command (also ``python -m bayesid``, ``bayesid.__main__``,
  and ``python -m bayesid.cli``, ``bayesid.cli.__main__``): one module per subcommand, :mod:`~bayesid.cli.simulate`,
  :mod:`~bayesid.cli.convert`, :mod:`~bayesid.cli.diagnose`, :mod:`~bayesid.cli.discover`,
  :mod:`~bayesid.cli.design`, :mod:`~bayesid.cli.fit`, :mod:`~bayesid.cli.predict`,
  :mod:`~bayesid.cli.sample`; :mod:`~bayesid.cli.options` (options
  shared by the subcommands, checks of numbers), :mod:`~bayesid.cli.inputs` (track files),
  :mod:`~bayesid.cli.outputs` (``--out`` folders), :mod:`~bayesid.cli.provenance`.
* :mod:`bayesid.tasks` -- under every layer: many independent tasks run serially, on joblib
  workers or on Dask, with a resumable journal; :class:`~bayesid.tasks.Runner` is the one object
  a step that runs tasks takes. ``bayesid._numba`` -- under every layer too: numba's threading
  layer, selected where the package first starts numba's threads.
"""

import importlib as _importlib

__version__ = "0.1.0"

#: name -> the module that defines it, imported at the name's first use (PEP 562)
_EXPORTS = {
    "Track": "bayesid.data.track",
    "read_csv": "bayesid.data.track",
    "write_csv": "bayesid.data.track",
    "load_any_vehicle": "bayesid.models",
    "build_model": "bayesid.models",
    "FitOptions": "bayesid.estimation.options",
    "identify": "bayesid.estimation.identification",
    "predict": "bayesid.estimation.prediction",
    "WindowProblem": "bayesid.estimation.windows",
    "SampleOptions": "bayesid.estimation.track_posterior",
    "sample_tracks": "bayesid.estimation.track_posterior",
    "DiagnoseOptions": "bayesid.analysis.gap.diagnose",
    "diagnose": "bayesid.analysis.gap.diagnose",
    "DiscoveryOptions": "bayesid.analysis.gap.discovery",
    "discover": "bayesid.analysis.gap.discovery",
    "Runner": "bayesid.tasks",
}

__all__ = list(_EXPORTS)

#: Former public names: ``{old: new}`` (the old name still resolves, with a DeprecationWarning).
_RENAMED = {"FitProblem": "WindowProblem"}


def __getattr__(name: str):
    """A name of :data:`__all__`, imported from its module at first use (then cached here)."""
    if name in _RENAMED:
        import warnings

        warnings.warn(
            f"bayesid.{name} is now bayesid.{_RENAMED[name]} (the same class)", DeprecationWarning, stacklevel=2
        )
        return __getattr__(_RENAMED[name])
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(_importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The module's names with those of :data:`__all__` not yet imported."""
    return sorted({*globals(), *__all__})
