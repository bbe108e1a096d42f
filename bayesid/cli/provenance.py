"""What produced a model: the package version, the vehicle file and the SHA-256 of every input;
and the check that a model's vehicle file has not changed since the fit."""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path


def file_sha256(path) -> str:
    """The SHA-256 of a file, streamed (a 300 MB log is not held in memory to hash it).

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    str
        The hex digest.
    """
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def vehicle_ref(arg: str) -> str:
    """How a model document names its vehicle: a file as its absolute path, a packaged id as given.

    Parameters
    ----------
    arg : str
        The ``--vehicle`` value.

    Returns
    -------
    str
        The absolute path of a file (a name with a suffix, or one that exists), else ``arg``.
    """
    p = Path(arg)
    return str(p.resolve()) if p.suffix or p.exists() else arg


def provenance(vehicle, input_sha256: dict) -> dict:
    """What produced a model.

    Parameters
    ----------
    vehicle : Vehicle or Ship
        The vehicle fitted (its ``file_path`` and ``coefficients``).
    input_sha256 : dict
        {input file: SHA-256}.

    Returns
    -------
    dict
        ``bayesid_version``, ``vehicle_file``, ``vehicle_sha256`` (None without a file),
        ``vehicle_coefficients`` and ``input_sha256``.
    """
    from .. import __version__

    vf = Path(vehicle.file_path) if vehicle.file_path else None
    return {
        "bayesid_version": __version__,
        "vehicle_file": str(vf) if vf else None,
        "vehicle_sha256": file_sha256(vf) if vf and vf.is_file() else None,
        "vehicle_coefficients": dict(vehicle.coefficients),
        "input_sha256": dict(input_sha256),
    }


def check_vehicle_unchanged(doc: dict, vehicle, model_path, allow: bool) -> None:
    """Refuse a model whose vehicle file changed after the fit.

    Parameters
    ----------
    doc : dict
        The model document (its ``provenance``).
    vehicle : Vehicle or Ship
        The vehicle loaded with the model.
    model_path : str or Path
        The model file, named in the message.
    allow : bool
        Print a warning instead of refusing.

    Raises
    ------
    ValueError
        The vehicle file's SHA-256 differs from the one recorded, and not ``allow``.
    """
    want = doc.provenance.get("vehicle_sha256")
    vf = Path(vehicle.file_path) if vehicle.file_path else None
    if want is None or vf is None or not vf.is_file():
        return
    if file_sha256(vf) != want:
        msg = (
            f"--model {model_path}: the vehicle file {vf} changed after the fit (SHA-256 differs); the "
            "non-free coefficients and particulars the model was fitted with may differ"
        )
        if not allow:
            raise ValueError(msg + "; pass --allow-changed-vehicle to predict anyway")
        print(f"WARNING: {msg}", file=sys.stderr)
