"""numba's threading layer for the package's parallel kernels, and its caches.

:func:`use_package_threading_layer` is called where the package may first start numba's thread
pool: where a model's compiled kernel is loaded (:func:`bayesid.models.codegen.kernel`,
:func:`bayesid.models.ship.kernel.kernel`) and where it sets the pool's size before a call
(:meth:`bayesid.models.simulate.Simulator.run`, a task in :mod:`bayesid.tasks`). Importing the
package leaves numba's configuration alone.

:func:`drop_stale_caches` runs when :mod:`bayesid.models` is imported. numba checks a cached
function against its own source file only: a cached caller keeps the callee (and the module
constants, such as the ship kernel's parameter layout) it was compiled with when another file
changes. Seen when the ship's coefficient layout grew by three: the cached closed-loop trial
(``ship.trials._run``) still read the old layout through the old ``ship.dynamics._rhs`` and failed
with a division by zero (with an extra hull term; without one it silently ignored the new
coefficients). So a digest of every source under ``bayesid/models`` is kept beside each of the
package's numba caches, and a cache whose digest differs is emptied.
"""

from __future__ import annotations

import functools
import hashlib
import os
from pathlib import Path

import numba

#: The file beside each numba cache of the package that holds the digest of the sources it was built from.
STAMP = "bayesid-sources.sha256"


def use_package_threading_layer() -> None:
    """Select numba's ``workqueue`` threading layer unless the user chose one
    (``NUMBA_THREADING_LAYER``). Call before the first parallel kernel runs (or numba's thread
    count is read or set): the layer is read when the pool starts, so a process that already
    started it keeps its layer."""
    # With the OpenMP layer, a parallel kernel call costs a floor of 6-8 ms on the 2-core machines
    # we measured (waking the pool), whatever its size: 15 tracks of a 600-step spiral take 7.7 ms
    # instead of 1.5 ms, which makes short batched calls (a sampler's half-ensemble, a Jacobian)
    # 3-5x slower. benchmarks/simulate.py prints the layer in use.
    if "NUMBA_THREADING_LAYER" not in os.environ:
        numba.config.THREADING_LAYER = "workqueue"


@functools.cache
def sources_digest(root: Path | None = None) -> str:
    """SHA-256 of every ``.py`` file under ``bayesid/models`` (names and contents, sorted), once
    per process.

    Parameters
    ----------
    root : Path, optional
        The ``models`` directory (default: the package's).

    Returns
    -------
    str
        The hex digest.
    """
    root = Path(__file__).parent / "models" if root is None else Path(root)
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        h.update(str(p.relative_to(root)).encode() + b"\0" + p.read_bytes() + b"\0")
    return h.hexdigest()


def numba_cache_dir(source: Path) -> Path | None:
    """Where numba caches the compiled functions of a source file: the locator numba itself picks
    (``NUMBA_CACHE_DIR``, the ``__pycache__`` beside the file, or the user-wide cache).

    Parameters
    ----------
    source : Path
        A Python source file.

    Returns
    -------
    Path or None
        The directory, or None when numba would not cache (or its locators cannot be asked).
    """
    try:  # numba's own choice (internal API: no cache dropped if it moves)
        from numba.core import caching

        impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # renamed in numba 0.61
        for cls in impl._locator_classes:
            loc = cls.from_function(use_package_threading_layer, str(source))
            if loc is not None:
                return Path(loc.get_cache_path())
    except Exception:  # noqa: BLE001 - a numba without these internals: nothing is dropped
        return None
    return None


def drop_stale_caches(root: Path | None = None, extra_dirs=()) -> list[Path]:
    """Empty the numba caches of the package's compiled modules whose stamp (:data:`STAMP`) does
    not match the sources' digest (:func:`sources_digest`), and stamp them.

    Parameters
    ----------
    root : Path, optional
        The ``models`` directory (default: the package's); its compiled modules are the ``.py``
        files in it and its subdirectories.
    extra_dirs : iterable of Path, default ()
        Other cache directories to check (the generated kernels' directory,
        :func:`bayesid.models.codegen.cache_dir`, whose modules import the package's constants).

    Returns
    -------
    list of Path
        The directories emptied (``.nbi`` and ``.nbc`` files removed).
    """
    root = Path(__file__).parent / "models" if root is None else Path(root)
    digest = sources_digest(root)
    dirs = {numba_cache_dir(d / "__init__.py") for d in [root, *(p for p in root.rglob("*") if p.is_dir())]}
    dirs |= {Path(d) for d in extra_dirs}
    dropped = []
    for d in sorted(x for x in dirs if x is not None and x.is_dir()):
        stamp = d / STAMP
        try:
            if stamp.is_file() and stamp.read_text().strip() == digest:
                continue
            for f in list(d.glob("*.nbi")) + list(d.glob("*.nbc")):
                f.unlink(missing_ok=True)
            stamp.write_text(digest + "\n")
            dropped.append(d)
        except OSError:  # a read-only cache: numba will not write there either
            continue
    return dropped


__all__ = ["use_package_threading_layer", "drop_stale_caches", "sources_digest", "numba_cache_dir", "STAMP"]
