"""The training's process runs its BLAS on one thread, unless the environment says otherwise."""

from __future__ import annotations

import os
import subprocess
import sys

PROBE = """
import ctypes
from tail_beam_id.study.blas_threads import single_blas_thread
limited = single_blas_thread()
counts = []
for path in limited:
    library = ctypes.CDLL(path)
    getter = next(
        getattr(library, n)
        for n in (
            "scipy_openblas_get_num_threads64_",
            "scipy_openblas_get_num_threads",
            "openblas_get_num_threads64_",
            "openblas_get_num_threads",
        )
        if hasattr(library, n)
    )
    counts.append(getter())
print(len(limited), sorted(set(counts)))
"""


def _probe(**env: str) -> str:
    clean = {
        k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")
    }
    result = subprocess.run(
        [sys.executable, "-c", PROBE],
        env={**clean, **env},
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    return result.stdout.strip()


def test_every_loaded_openblas_is_limited_to_one_thread():
    """numpy's and scipy's OpenBLAS are both found and each reports one thread."""
    limited, counts = _probe().split(" ", 1)
    assert int(limited) >= 1 and counts == "[1]"


def test_a_thread_count_set_in_the_environment_is_left_alone():
    """OPENBLAS_NUM_THREADS set: no library is limited."""
    assert _probe(OPENBLAS_NUM_THREADS="2") == "0 []"
