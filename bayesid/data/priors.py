"""The ``[prior]`` section of a vehicle file: what a towing tank (captive tests) says about the
coefficients, with its error, as independent Gaussian priors. Coefficients without an entry keep
a uniform prior inside the model's bounds.

Layout (prime values, the file's ``[coefficients]`` units)::

    [prior]
    source = "Yasukawa & Yoshimura (2015) captive tests; relative sds stated below"
    rel_sd = 0.2                               # default for the names in `coefficients`
    coefficients = ["Yv", "Yr", "Nv", "Nr"]    # mean: the file's [coefficients] value
    Xvv = { rel_sd = 0.3 }                     # one coefficient: relative sd of the file's value
    Yvvr = { mean = 0.38, sd = 0.12 }          # or an explicit mean and absolute sd

A name the vehicle does not know, a non-positive or non-finite sd, a relative sd of a zero mean,
a name given twice and an unknown key are errors that name the file and the coefficient.
"""

from __future__ import annotations

import math

__all__ = ["parse_prior_section"]


def parse_prior_section(section: dict, path, values: dict, known, error=ValueError) -> tuple[dict, str]:
    """Gaussian priors of a vehicle file's ``[prior]`` section.

    Parameters
    ----------
    section : dict
        The parsed TOML table (empty or None: no priors).
    path : str or path-like
        The file, named in every message.
    values : dict
        ``{name: value}`` of the file's coefficients (prime form); the default means.
    known : container of str
        The coefficient names the vehicle family accepts.
    error : type, default ValueError
        Exception class raised (the loader's file error).

    Returns
    -------
    priors : dict
        ``{name: (mean, sd)}``, the Gaussian prior of each coefficient with an entry (prime form).
    source : str
        The section's ``source`` text ("" when not given).

    Raises
    ------
    error
        On any fault of the section listed in the module docstring; the message names the file,
        the section and the coefficient.
    """
    section = dict(section or {})
    source = str(section.pop("source", ""))
    default_rel = section.pop("rel_sd", None)
    listed = section.pop("coefficients", [])
    if not isinstance(listed, list):
        raise error(f"{path}: [prior] coefficients must be a list of names")
    entries: dict = {}
    for name in listed:
        if default_rel is None:
            raise error(f"{path}: [prior] coefficients lists {name!r} but no rel_sd is given for the list")
        if name in entries:
            raise error(f"{path}: [prior] {name} given twice")
        entries[name] = {"rel_sd": default_rel}
    for name, spec in section.items():
        if not isinstance(spec, dict):
            raise error(f"{path}: [prior] {name} = {spec!r}: give {{ rel_sd = ... }} or {{ mean = ..., sd = ... }}")
        if name in entries:
            raise error(f"{path}: [prior] {name} given twice (in the list and on its own)")
        entries[name] = spec
    out = {}
    for name, spec in entries.items():
        if name not in known:
            raise error(f"{path}: [prior] unknown coefficient {name!r}")
        bad = set(spec) - {"mean", "sd", "rel_sd"}
        if bad:
            raise error(f"{path}: [prior] {name}: unknown key(s) {sorted(bad)}; use mean, sd or rel_sd")
        for k, v in spec.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise error(f"{path}: [prior] {name}: {k} = {v!r} is not a finite number")
        mean = float(spec.get("mean", values.get(name, 0.0)))
        if ("sd" in spec) == ("rel_sd" in spec):
            raise error(f"{path}: [prior] {name}: give exactly one of sd and rel_sd")
        if "sd" in spec:
            sd = float(spec["sd"])
            if not sd > 0:
                raise error(f"{path}: [prior] {name}: sd must be positive, not {spec['sd']!r}")
        else:
            rel = float(spec["rel_sd"])
            if not rel > 0:
                raise error(f"{path}: [prior] {name}: rel_sd must be positive, not {spec['rel_sd']!r}")
            if mean == 0.0:
                raise error(f"{path}: [prior] {name}: a relative sd of a zero mean; give an absolute sd")
            sd = rel * abs(mean)
        out[name] = (mean, sd)
    if default_rel is not None and not listed:
        raise error(f"{path}: [prior] rel_sd is given but no coefficients list uses it")
    return out, source
