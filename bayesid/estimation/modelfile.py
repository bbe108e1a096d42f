"""The model file (``model.json``) that ``bayesid fit`` writes and ``predict``, ``sample`` and the
studies read: :class:`ModelDocument` is its only reader and writer.

A document holds what is needed to rebuild the fitted model (vehicle file reference, free
coefficients, effects, step, input reconstruction), the optimum and its Laplace covariance, the
fit's weights, scores and settings, the prior and calibration summaries, and the provenance of
the fit (package version, vehicle file hash and values, input hashes).
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..models import build_model, load_any_vehicle
from ..models.context import INPUT_RECONSTRUCTIONS
from ..tasks import jsonable
from .calibration import Calibration
from .laplace import psd_covariance

__all__ = ["FORMAT", "ModelDocument", "load_model"]

#: the format of the documents this module writes (and the only one it reads)
FORMAT = "bayesid-model-1"

_REQUIRED = ("vehicle", "free", "effects", "dt", "p", "cov")
# fields without a default: None when a hand-written or older file lacks them
_WITHOUT_DEFAULT = ("vehicle_id", "fit_window_s", "param_names", "sd", "start", "posterior", "seed", "noise_sd")


@dataclass
class ModelDocument:
    """A fitted model as ``model.json`` stores it (format :data:`FORMAT`).

    Parameters
    ----------
    vehicle : str
        The vehicle file as the user named it (packaged id or path; a relative path is read
        relative to the model file first).
    vehicle_id : str
        The vehicle's id.
    free : list of str
        The free coefficients.
    effects : list of str
        The effects in the model.
    dt : float
        The model step (s).
    fit_window_s : float
        The multiple-shooting window of the fit (s).
    param_names : list of str
        The names of the parameters ``p`` (coefficients, then effect parameters).
    p : list of float
        The optimum, ``(n_params,)``.
    cov : list of list of float
        Its Laplace covariance, ``(n_params, n_params)``.
    sd : list of float
        The square roots of the covariance's diagonal.
    start : list of float
        The start of the fit (``(n_params,)``).
    posterior : dict
        The Laplace summary (residual variance, AR(1) inflation, condition number, weak
        directions).
    seed : dict
        The equation-error seed's summary.
    noise_sd : dict
        ``{channel: noise sd}`` estimated from the tracks.
    weighting : str, default "noise"
        ``"noise"`` or ``"residual"``: the channel weights of the fit.
    fit_sd : dict, optional
        ``{channel: sd}`` of the final weights (None: ``noise_sd``).
    fit_channels : list of str, optional
        The scored channels (None: every measured one).
    start_rule : str, default "measured"
        The window start rule the fit used.
    inputs : str, default "hold"
        How the fit reconstructed the logged inputs between samples
        (``inputs`` of :class:`bayesid.estimation.options.FitOptions`); the model built from the
        document does the same (files from before the option: ``"hold"``).
    rudder_rate_deg_s : float, optional
        The gear's rate of ``inputs`` ``"rate"``, deg/s (written only then).
    train_runs : list of str
        The training runs' names.
    train_scores : dict
        The fit's pooled scores on its training runs.
    provenance : dict
        Package version, vehicle file hash and values, input hashes, warnings, command.
    fit : dict
        ``ssr``, ``n_residuals``, ``nfev``, ``success``, ``message``, ``seconds``, ``bic``, and
        ``at_bound`` (the coefficients the fit left on a bound, when any).
    multistart : dict, optional
        The multistart summary, when the fit had extra starts.
    training_turns : list of dict, optional
        Whether the model reproduces the turning circles among its training runs
        (:func:`bayesid.estimation.prediction.training_turns`), when there are any.
    prior : dict, default {"used": False}
        The vehicle file's prior as used (``{"used": False}`` without one).
    calibration : Calibration, optional
        The leave-one-run-out calibration of the predictive bands (a dict, as the file stores it,
        is read with :meth:`~bayesid.estimation.calibration.Calibration.from_dict`).
    posterior_source : dict, optional
        Set when ``p`` and ``cov`` come from ``bayesid sample`` (its ``sample.json``, method,
        convergence).
    path : Path, optional
        The file the document was read from (not stored).
    """

    vehicle: str
    vehicle_id: str
    free: list
    effects: list
    dt: float
    fit_window_s: float
    param_names: list
    p: list
    cov: list
    sd: list
    start: list
    posterior: dict
    seed: dict
    noise_sd: dict
    weighting: str = "noise"
    fit_sd: dict | None = None
    fit_channels: list | None = None
    start_rule: str = "measured"
    inputs: str = "hold"
    rudder_rate_deg_s: float | None = None
    train_runs: list = field(default_factory=list)
    train_scores: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    fit: dict = field(default_factory=dict)
    multistart: dict | None = None
    training_turns: list | None = None
    prior: dict = field(default_factory=lambda: {"used": False})
    calibration: Calibration | None = None
    posterior_source: dict | None = None
    path: Path | None = field(default=None, compare=False, repr=False)

    def __post_init__(self):
        if self.fit_sd is None:
            self.fit_sd = self.noise_sd
        if isinstance(self.calibration, dict):
            self.calibration = Calibration.from_dict(self.calibration)

    @classmethod
    def from_identify(cls, result, vehicle_ref: str, train_names, provenance: dict | None = None) -> ModelDocument:
        """The document of an identification.

        Parameters
        ----------
        result : IdentifyResult
            What :func:`bayesid.estimation.identification.identify` returned.
        vehicle_ref : str
            The vehicle file as the user named it.
        train_names : list of str
            The training runs' names.
        provenance : dict, optional
            Package version, vehicle file hash and values, input hashes (stored as given).

        Returns
        -------
        ModelDocument
            The document (optimum, covariance, weights, scores, settings, summaries).
        """
        m, f = result.model, result.fit
        return cls(
            vehicle=vehicle_ref,
            vehicle_id=m.vehicle.id,
            free=list(m.free),
            effects=[e.name for e in m.effects],
            dt=m.dt,
            fit_window_s=result.window_s,
            param_names=m.param_names,
            p=f.p.tolist(),
            cov=result.cov.tolist(),
            sd=np.sqrt(np.clip(np.diag(result.cov), 0, None)).tolist(),
            start=result.p0.tolist(),
            posterior=result.posterior,
            seed=result.seed,
            noise_sd=result.noise_sd,
            weighting=result.weighting,
            fit_sd=result.fit_sd,
            fit_channels=None if result.channels is None else list(result.channels),
            start_rule=result.start_rule,
            inputs=getattr(m, "inputs", "hold"),
            rudder_rate_deg_s=getattr(m, "rudder_rate_deg_s", None),
            train_runs=list(train_names),
            train_scores=result.train_scores,
            provenance=provenance or {},
            fit={
                "ssr": f.cost,
                "n_residuals": f.n_residuals,
                "nfev": f.n_simulations,
                "success": f.success,
                "message": f.message,
                "seconds": f.wall_s,
                "bic": f.bic,
                **({"at_bound": list(f.at_bound)} if f.at_bound else {}),
                **({} if getattr(result, "step_check", None) is None else {"step_check": result.step_check.to_dict()}),
                **({} if getattr(result, "retimed_moves", None) is None else {"retimed_moves": result.retimed_moves}),
                **({} if getattr(result, "nested_start", None) is None else {"nested_start": result.nested_start}),
                **(
                    {"training_points": result.training_points}
                    if (getattr(result, "training_points", None) or {}).get("apart")
                    else {}
                ),
            },
            multistart=None if result.multistart is None else result.multistart.to_dict(),
            prior=result.prior or {"used": False},
            calibration=result.calibration,
        )

    def to_dict(self) -> dict:
        """The JSON object of the document.

        Returns
        -------
        dict
            ``format`` then the fields in their order (``multistart``, ``training_turns`` and
            ``posterior_source`` only when set; ``inputs`` only when not ``"hold"``, ``rudder_rate_deg_s`` only when set; ``path`` never; ``calibration`` as
            :meth:`~bayesid.estimation.calibration.Calibration.to_dict`).
        """
        d = {"format": FORMAT}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if (f.name == "inputs" and v == "hold") or (f.name == "rudder_rate_deg_s" and v is None):
                continue  # the defaults, as in every file from before the options
            if f.name != "path" and not (f.name in ("multistart", "training_turns", "posterior_source") and v is None):
                d[f.name] = v.to_dict() if isinstance(v, Calibration) else v
        return d

    def to_json(self, path) -> None:
        """Write the document (the report layer's JSON conventions: NaN as null).

        Parameters
        ----------
        path : str or Path
            The file; its folder is created when missing.
        """
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(jsonable(self.to_dict()), indent=2) + "\n")

    @classmethod
    def from_json(cls, path) -> ModelDocument:
        """Read a document, checking its format and the fields a model needs.

        Parameters
        ----------
        path : str or Path
            A ``model.json`` written by ``bayesid fit`` (or ``posterior_model.json`` by
            ``bayesid sample``).

        Returns
        -------
        ModelDocument
            With defaults for the optional fields that older files lack.

        Raises
        ------
        ValueError
            Naming the file when it is not JSON, not of format :data:`FORMAT`, or lacks one of
            ``vehicle, free, effects, dt, p, cov`` or has them of the wrong type.
        """
        path = Path(path)
        try:
            raw = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError) as e:
            raise ValueError(f"{path}: not a model file ({e})") from None
        if not isinstance(raw, dict) or raw.get("format") != FORMAT:
            got = raw.get("format") if isinstance(raw, dict) else None
            raise ValueError(f"{path}: not a bayesid model file (format {got!r})")
        missing = [k for k in _REQUIRED if k not in raw]
        if missing:
            raise ValueError(f"{path}: model file without {', '.join(repr(k) for k in missing)} (edited or truncated?)")
        if (
            not isinstance(raw["vehicle"], str)
            or not isinstance(raw["free"], list)
            or not isinstance(raw["effects"], list)
        ):
            raise ValueError(f"{path}: 'vehicle' must be a string, 'free' and 'effects' lists")
        names = {f.name for f in dataclasses.fields(cls)} - {"path"}
        kw = {k: raw.get(k) for k in names if k in raw or k in _WITHOUT_DEFAULT}
        doc = cls(**kw)
        doc.provenance = doc.provenance or {}
        doc.prior = doc.prior or {"used": False}
        doc.path = path
        return doc

    def vehicle_path(self) -> str:
        """The vehicle reference, relative paths resolved against the model file's folder first.

        Returns
        -------
        str
            The path of the vehicle file next to the model file when there is one, else the
            reference as stored.
        """
        ref = self.vehicle
        if self.path is not None and not Path(ref).is_absolute() and (self.path.parent / ref).is_file():
            return str(self.path.parent / ref)
        return ref

    def build(self):
        """The fitted model, its optimum and covariance.

        Returns
        -------
        model : SimulationModel
            The model of the vehicle with the document's free coefficients, effects and step.
        p : ndarray, shape (n_params,)
            The optimum.
        cov : ndarray, shape (n_params, n_params)
            Its covariance, symmetric positive semi-definite (round-off of the writer removed).

        Raises
        ------
        ValueError
            Naming the file when the vehicle does not load, the coefficients or effects do not
            fit it, ``dt`` is not positive, ``inputs`` is unknown, ``p`` is not finite with one
            value per parameter, or ``cov`` is not a symmetric positive semi-definite matrix of
            that size.
        """
        path, ref = self.path, self.vehicle_path()
        vehicle = load_any_vehicle(ref)
        if not isinstance(self.dt, (int, float)) or not self.dt > 0:
            raise ValueError(f"{path}: 'dt' must be a positive number of seconds, not {self.dt!r}")
        if self.inputs not in INPUT_RECONSTRUCTIONS:
            raise ValueError(f"{path}: 'inputs' must be one of {', '.join(INPUT_RECONSTRUCTIONS)}, not {self.inputs!r}")
        try:
            model = build_model(
                vehicle, self.free, self.effects, self.dt, inputs=self.inputs, rudder_rate_deg_s=self.rudder_rate_deg_s
            )
        except (KeyError, ValueError) as e:
            raise ValueError(
                f"{path}: its free coefficients or effects do not fit the vehicle {ref!r}: {e.args[0] if e.args else e}"
            ) from None
        n = len(model.param_names)
        try:
            p, cov = np.array(self.p, dtype=float), np.array(self.cov, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{path}: 'p' and 'cov' must be numbers") from None
        if p.shape != (n,) or not np.all(np.isfinite(p)):
            raise ValueError(
                f"{path}: 'p' must be {n} finite numbers ({', '.join(model.param_names)}), got shape {p.shape}"
            )
        if cov.shape != (n, n) or not np.all(np.isfinite(cov)):
            raise ValueError(
                f"{path}: 'cov' must be a finite {n} x {n} matrix, got shape {cov.shape}"
                + ("" if cov.shape != (n, n) else " with non-finite entries")
            )
        # round-off of an ill-conditioned inverse (relative asymmetry ~1e-7, eigenvalues ~-1e-9 of
        # the largest) is not an edit; an asymmetry or a negative eigenvalue beyond 1e-6 is
        big = max(float(np.abs(cov).max()), 1e-300)
        lam = np.linalg.eigvalsh(0.5 * (cov + cov.T))
        if np.abs(cov - cov.T).max() > 1e-6 * big or lam.min() < -1e-6 * max(float(lam.max()), 1e-300):
            raise ValueError(
                f"{path}: 'cov' is not a symmetric positive semi-definite matrix (edited?): relative "
                f"asymmetry {np.abs(cov - cov.T).max() / big:.2g}, smallest/largest eigenvalue "
                f"{lam.min() / max(float(lam.max()), 1e-300):.2g}"
            )
        return model, p, psd_covariance(cov)

    def with_posterior(self, p, cov, source: dict) -> ModelDocument:
        """A copy whose optimum and covariance are a sampled posterior's (``bayesid sample``).

        Parameters
        ----------
        p : array_like, shape (n_params,)
            The posterior mode.
        cov : array_like, shape (n_params, n_params)
            The draws' covariance (made positive semi-definite here).
        source : dict
            ``sample`` (path of sample.json), ``method``, ``converged``.

        Returns
        -------
        ModelDocument
            The vehicle reference resolved to an absolute path when the file named it relative to
            its own folder.
        """
        cov = psd_covariance(cov)
        ref = self.vehicle_path()
        vehicle = str(Path(ref).resolve()) if ref != self.vehicle else self.vehicle
        return dataclasses.replace(
            self,
            vehicle=vehicle,
            p=np.asarray(p, float).tolist(),
            cov=cov.tolist(),
            sd=np.sqrt(np.diag(cov)).tolist(),
            posterior_source=dict(source),
        )


def load_model(path):
    """The fitted model of a ``model.json``.

    Parameters
    ----------
    path : str or Path
        The model file.

    Returns
    -------
    model : SimulationModel
        The fitted model (:meth:`ModelDocument.build`).
    p : ndarray, shape (n_params,)
        The optimum.
    cov : ndarray, shape (n_params, n_params)
        Its covariance.
    doc : ModelDocument
        The document.

    Raises
    ------
    ValueError
        Naming the file (:meth:`ModelDocument.from_json`, :meth:`ModelDocument.build`).
    """
    doc = ModelDocument.from_json(path)
    model, p, cov = doc.build()
    return model, p, cov, doc
