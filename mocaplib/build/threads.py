"""How many BLAS/OpenMP threads the libraries of numpy and scipy run: one, unless the user
sets :data:`THREAD_VARIABLES`. The command line, the build's worker processes and every build
task follow it, so the same inputs give the same bits whatever ``--jobs`` or the machine.
Standard library only: the command line loads it first, before numpy.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from contextlib import contextmanager

#: Thread-count variables of the BLAS/OpenMP libraries numpy and scipy may use.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


@contextmanager
def single_threaded_workers():
    """Worker processes started inside get one BLAS thread each (unless the user chose a
    number): with one process per core, more threads only compete for the same cores."""
    unset = [name for name in THREAD_VARIABLES if name not in os.environ]
    os.environ.update({name: "1" for name in unset})
    try:
        yield
    finally:
        for name in unset:
            os.environ.pop(name, None)


def one_thread_by_default() -> None:
    """Give the BLAS/OpenMP libraries one thread each, unless the user chose a number
    (:data:`THREAD_VARIABLES`) or numpy is loaded already (its libraries read the variables
    when they load). The command line calls it first: the fit's batched small matrices gain
    nothing from more threads (on a busy 2-core machine they lose several times over), and a
    command then computes what a build's task (:func:`pinned`) computes, to the last bit."""
    if "numpy" not in sys.modules:
        for name in THREAD_VARIABLES:
            os.environ.setdefault(name, "1")


def pinned(function: Callable, /, *arguments):
    """``function(*arguments)`` with the BLAS/OpenMP libraries of numpy and scipy limited to
    one thread: a multi-threaded BLAS splits sums in an order that depends on its thread
    count, so the last bits of results would depend on ``--jobs`` and the machine."""
    import numpy  # noqa: F401  (loaded first: the limit applies to loaded libraries)
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        return function(*arguments)
