"""A vehicle file with discovered terms added (``bayesid diagnose --write-vehicle``,
``bayesid discover --write-vehicle``): the source file's text, unchanged, with each kept term
inserted at the top of ``[coefficients]`` (its refitted value, a comment saying where it comes
from; a term the section already gives, at 0, gets its value replaced in place) and appended to
a ship file's ``[fit] free`` list, so ``bayesid fit`` re-identifies it with the others. A named
model form (a ship's ``[form] coupling_speed``) is written into the ``[form]`` section, which is
added at the end of the file when the source has none."""

from __future__ import annotations

import re
from pathlib import Path

__all__ = ["vehicle_with_terms", "write_vehicle_with_terms"]

_FREE = re.compile(r"^(free\s*=\s*\[)([^\]]*)(\])", re.M)


def vehicle_with_terms(source_text: str, terms: dict, note: str, forms: dict | None = None) -> str:
    """The text of a vehicle file with terms added.

    A term the file's ``[coefficients]`` already gives (a listed coefficient at 0, such as a
    submarine's ``Nprop``) gets its value replaced in place, the old value kept in the comment;
    the others are inserted at the top of the section.

    Parameters
    ----------
    source_text : str
        The source vehicle file (TOML).
    terms : dict
        ``{name: prime value}`` of the terms to add.
    note : str
        The comment written after each added or replaced line.
    forms : dict, optional
        ``{key: choice}`` of the ``[form]`` section to set (a ship's model-form choices).

    Returns
    -------
    str
        The new text.

    Raises
    ------
    ValueError
        When the source has no ``[coefficients]`` section.
    """
    lines = source_text.splitlines()
    try:
        at = next(i for i, ln in enumerate(lines) if ln.strip() == "[coefficients]")
    except StopIteration:
        raise ValueError("the vehicle file has no [coefficients] section") from None
    end = next((i for i in range(at + 1, len(lines)) if lines[i].lstrip().startswith("[")), len(lines))
    new = dict(terms)
    for i in range(at + 1, end):
        m = re.match(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=\s*([^#]*?)\s*(#.*)?$", lines[i])
        if m is not None and m.group(1) in new:
            name = m.group(1)
            lines[i] = f"{name} = {new.pop(name)!r}  # {note} (was {m.group(2)})"
    added = [f"{name} = {value!r}  # {note}" for name, value in new.items()]
    text = "\n".join(lines[: at + 1] + added + lines[at + 1 :]) + "\n"
    m = _FREE.search(text)
    if m is not None:  # a ship file's [fit] free: the new terms are fitted too
        items = [x.strip() for x in m.group(2).split(",") if x.strip()]
        items += [f'"{n}"' for n in terms if f'"{n}"' not in items]
        text = text[: m.start()] + m.group(1) + ", ".join(items) + m.group(3) + text[m.end() :]
    return _with_forms(text, forms or {}, note)


def _with_forms(text: str, forms: dict, note: str) -> str:
    """``text`` with the ``[form]`` keys of ``forms`` set: replaced in place where the section
    gives them, else added at its top; the section appended when the file has none."""
    if not forms:
        return text
    lines = text.rstrip("\n").splitlines()
    line = {k: f"{k} = {_toml_value(v)}  # {note}" for k, v in forms.items()}
    at = next((i for i, ln in enumerate(lines) if ln.strip() == "[form]"), None)
    if at is None:
        return "\n".join(lines + ["", "[form]"] + list(line.values())) + "\n"
    end = next((i for i in range(at + 1, len(lines)) if lines[i].lstrip().startswith("[")), len(lines))
    todo = dict(line)
    for i in range(at + 1, end):
        m = re.match(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=", lines[i])
        if m is not None and m.group(1) in todo:
            lines[i] = todo.pop(m.group(1))
    return "\n".join(lines[: at + 1] + list(todo.values()) + lines[at + 1 :]) + "\n"


def _toml_value(v) -> str:
    """A string or number as TOML writes it."""
    return f'"{v}"' if isinstance(v, str) else repr(float(v))


def write_vehicle_with_terms(
    source, terms: dict, path, note: str, overwrite: bool = False, forms: dict | None = None
) -> Path:
    """Write a vehicle file with terms added and check that it loads.

    Parameters
    ----------
    source : str or Path
        The source vehicle file.
    terms : dict
        ``{name: prime value}``.
    path : str or Path
        The file to write.
    note : str
        The comment of each added line.
    overwrite : bool, default False
        Replace an existing file.
    forms : dict, optional
        ``{key: choice}`` of the ``[form]`` section (:func:`vehicle_with_terms`).

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    ValueError
        As :func:`vehicle_with_terms`, or when the written file does not load (the message names it).
    """
    from ..models import load_any_vehicle

    path = Path(path)
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path} exists: give another --write-vehicle path or --overwrite")
    text = vehicle_with_terms(Path(source).read_text(), terms, note, forms)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    try:
        load_any_vehicle(path)
    except Exception as exc:  # noqa: BLE001 - said with the file's name
        raise ValueError(f"{path}: the written vehicle file does not load: {exc}") from None
    return path
