"""A vehicle file with discovered terms added (``bayesid diagnose --write-vehicle``,
``bayesid discover --write-vehicle``): the source file's text, unchanged, with each kept term
inserted at the top of ``[coefficients]`` (its refitted value, a comment saying where it comes
from) and appended to a ship file's ``[fit] free`` list, so ``bayesid fit`` re-identifies it with
the others."""

from __future__ import annotations

import re
from pathlib import Path

__all__ = ["vehicle_with_terms", "write_vehicle_with_terms"]

_FREE = re.compile(r"^(free\s*=\s*\[)([^\]]*)(\])", re.M)


def vehicle_with_terms(source_text: str, terms: dict, note: str) -> str:
    """The text of a vehicle file with terms added.

    Parameters
    ----------
    source_text : str
        The source vehicle file (TOML).
    terms : dict
        ``{name: prime value}`` of the terms to add.
    note : str
        The comment written after each added line.

    Returns
    -------
    str
        The new text.

    Raises
    ------
    ValueError
        When the source has no ``[coefficients]`` section, or already gives one of the terms.
    """
    lines = source_text.splitlines()
    try:
        at = next(i for i, ln in enumerate(lines) if ln.strip() == "[coefficients]")
    except StopIteration:
        raise ValueError("the vehicle file has no [coefficients] section") from None
    for name in terms:
        if re.search(rf"^\s*{re.escape(name)}\s*=", source_text, re.M):
            raise ValueError(f"the vehicle file already gives {name}")
    added = [f"{name} = {value!r}  # {note}" for name, value in terms.items()]
    text = "\n".join(lines[: at + 1] + added + lines[at + 1 :]) + "\n"
    m = _FREE.search(text)
    if m is not None:  # a ship file's [fit] free: the new terms are fitted too
        items = [x.strip() for x in m.group(2).split(",") if x.strip()]
        items += [f'"{n}"' for n in terms if f'"{n}"' not in items]
        text = text[: m.start()] + m.group(1) + ", ".join(items) + m.group(3) + text[m.end() :]
    return text


def write_vehicle_with_terms(source, terms: dict, path, note: str, overwrite: bool = False) -> Path:
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
    text = vehicle_with_terms(Path(source).read_text(), terms, note)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    try:
        load_any_vehicle(path)
    except Exception as exc:  # noqa: BLE001 - said with the file's name
        raise ValueError(f"{path}: the written vehicle file does not load: {exc}") from None
    return path
