"""One BLAS thread where urident's numerical work is many small products, factorisations and
solves: on a loaded 2-core machine a second OpenBLAS thread only spins and waits (measurements:
docs/scale.md, docs/excitation.md)."""

from __future__ import annotations

import contextlib
import ctypes
import functools
import glob
import os

import numpy as np


@functools.lru_cache(maxsize=1)
def _openblas_threads() -> tuple:
    """(get, set) of the thread count of each bundled OpenBLAS: numpy's and scipy's (scipy.linalg
    has its own copy); empty with another BLAS."""
    site = os.path.join(os.path.dirname(np.__file__), os.pardir)
    out = []
    for libs, suffix in (("numpy.libs", "64_"), ("scipy.libs", "")):
        for lib in glob.glob(os.path.join(site, libs, "*openblas*")):
            try:
                dll = ctypes.CDLL(lib)
                out.append((getattr(dll, f"scipy_openblas_get_num_threads{suffix}"),
                            getattr(dll, f"scipy_openblas_set_num_threads{suffix}")))
                break
            except (OSError, AttributeError):
                continue
    return tuple(out)


@contextlib.contextmanager
def one_blas_thread():
    """numpy's and scipy's OpenBLAS on one thread within: LAPACK's QR of a tall, narrow chunk
    measured 32 ms single-threaded vs 470 ms with two OpenBLAS threads on a loaded 2-core machine
    (the threads wait on each other); small triangular solves alike."""
    fns = _openblas_threads()
    before = [get() for get, _ in fns]
    for _, set_threads in fns:
        set_threads(1)
    try:
        yield
    finally:
        for (_, set_threads), n in zip(fns, before):
            set_threads(n)
