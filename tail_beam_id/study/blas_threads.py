"""One BLAS thread for the training's process.

The training's products are small (a network of 16 hidden units, fits over a few thousand
records): a second BLAS thread saves nothing on them, and on a shared machine the library's
threads wait for each other at every call (L-BFGS-B makes thousands), which costs more than
the work. Set before the first product, one thread also gives the same floats on any machine.
An explicit ``OPENBLAS_NUM_THREADS`` or ``OMP_NUM_THREADS`` in the environment is left as set.
"""

from __future__ import annotations

import ctypes
import os

# What OpenBLAS builds call their thread setter (numpy's and scipy's wheels rename it).
SETTERS = (
    "scipy_openblas_set_num_threads64_",
    "scipy_openblas_set_num_threads",
    "openblas_set_num_threads64_",
    "openblas_set_num_threads",
)
THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")


def single_blas_thread() -> list[str]:
    """Limit every OpenBLAS loaded in this process to one thread (unless the environment sets
    the count); returns the libraries limited (empty: none loaded, or the environment
    decides). Linux: the libraries are found in /proc/self/maps."""
    if any(os.environ.get(name) for name in THREAD_VARIABLES):
        return []
    # numpy and scipy each load their own OpenBLAS: both are limited
    import numpy  # noqa: F401
    import scipy.linalg  # noqa: F401

    try:
        with open("/proc/self/maps", encoding="utf-8") as maps:
            paths = sorted(
                {line.split()[-1] for line in maps if "openblas" in line.split()[-1].lower()}
            )
    except OSError:
        return []
    limited = []
    for path in paths:
        try:
            library = ctypes.CDLL(path)
        except OSError:
            continue
        setter = next((getattr(library, n) for n in SETTERS if hasattr(library, n)), None)
        if setter is not None:
            setter(1)
            limited.append(path)
    return limited
