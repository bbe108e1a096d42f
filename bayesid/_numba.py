"""numba's threading layer for the package's parallel kernels.

:func:`use_package_threading_layer` is called where the package may first start numba's thread
pool: where a model's compiled kernel is loaded (:func:`bayesid.models.codegen.kernel`,
:func:`bayesid.models.ship.kernel.kernel`) and where it sets the pool's size before a call
(:meth:`bayesid.models.simulate.Simulator.run`, a task in :mod:`bayesid.tasks`). Importing the
package leaves numba's configuration alone.
"""

from __future__ import annotations

import os

import numba


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


__all__ = ["use_package_threading_layer"]
