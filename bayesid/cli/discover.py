"""``bayesid discover``: structure discovery on a fitted model -- the terms the model lacks,
refitted and checked on held-out tracks (:mod:`bayesid.analysis.gap.discovery`) -- written as
``diagnosis.json`` (its ``discovery`` entry), ``report.md`` and figures; ``--write-vehicle``
writes the vehicle file with the kept terms added."""

from __future__ import annotations

from . import options as opt
from .inputs import naming_files, read_tracks


def add_parser(sub) -> None:
    """Declare ``bayesid discover`` and its options.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The subparsers of the ``bayesid`` parser.
    """
    add_options(opt.add_subcommand(sub, "discover", "structure discovery: the model terms the data say are missing"))


def add_options(d) -> None:
    """The options ``discover`` and ``design`` share.

    Parameters
    ----------
    d : argparse.ArgumentParser
        The subcommand's parser.
    """
    d.add_argument("--model", required=True, help="model.json written by bayesid fit (the reference model)")
    opt.add_tracks(d, "--train", "training Track CSVs (the reference model is refitted on them)")
    opt.add_tracks(d, "--heldout", "held-out Track CSVs (the kept terms must improve these)")
    opt.add_score_window(d)
    opt.add_start(d)
    opt.add_leadin(d)
    opt.add_max_nfev(d, "least-squares iterations per fit")
    opt.add_floor(d)
    opt.add_seed(d, "random seed (noise floor, bootstrap of the sparse regression)")
    opt.add_discovery(d, default_on=False)
    opt.add_jobs(d)
    opt.add_out(d, "output folder")
    opt.add_overwrite(d)


def run(args) -> int:
    """Run ``bayesid discover``: refit the model of ``--model`` on ``--train`` (its free
    coefficients from their fitted values, its effects, the fit's reading of the logged inputs:
    ``bayesid fit --inputs``), score it on ``--heldout`` against the noise floor, and search the
    term library when the gap is significant.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options.

    Returns
    -------
    int
        The exit code (0).
    """
    discover(args)
    return 0


def discover(args):
    """``bayesid discover``'s work (the report written); also ``bayesid design``'s.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed options.

    Returns
    -------
    Diagnosis
        The diagnosis written.
    """
    from ..analysis.gap.discovery import check_compare
    from ..estimation.modelfile import ModelDocument
    from ..models import load_any_vehicle
    from .diagnose import check_outputs, diagnose_options, run_and_write

    check_outputs(args)  # the same outputs as bayesid diagnose
    doc = ModelDocument.from_json(args.model)
    vehicle = load_any_vehicle(doc.vehicle_path())
    model = doc.build()[0]  # the document's coefficients and effects fit the vehicle (else a named error)
    vehicle = vehicle.with_coefficients(dict(zip(doc.free, doc.p[: len(doc.free)])))
    got = read_tracks([("--train", args.train), ("--heldout", args.heldout)], vehicle)
    found, design = opt.discovery_options(args)
    check_compare(model, found)
    with naming_files(got):
        options = diagnose_options(
            args,
            candidates=(),
            base_effects=tuple(doc.effects),
            fit_window_s=doc.fit_window_s,
            dt=doc.dt,
            weighting=doc.weighting,
            discover=found,
            design=design,
            # the fit's reading of the logged inputs (bayesid fit --inputs), for every model refitted
            inputs=doc.inputs,
            rudder_rate_deg_s=doc.rudder_rate_deg_s if doc.inputs == "rate" else None,
        )
        return run_and_write(args, vehicle, list(doc.free), got, options)
