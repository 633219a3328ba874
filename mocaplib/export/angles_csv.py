"""Joint coordinates as CSV: a ``time_s`` column, then one column per DOF.

The header is ``time_s`` and :data:`mocaplib.skeleton.DOF_NAMES`; each row is one frame, every
number written with ``%.{digits}g`` (radians, ``pelvis_t*`` metres, seconds), NaN as an empty
field, lines ending in ``\\n``: the bytes ``pandas.DataFrame.to_csv(float_format="%.9g")``
writes for :attr:`mocaplib.model.motion.Motion.angles`, without importing pandas.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import MocapError
from ..io.atomic import atomic_write_text
from ..skeleton import DOF_NAMES


def write_angles_csv(path: str | os.PathLike, time: np.ndarray, q: np.ndarray, /, *,
                     digits: int = 9) -> Path:
    """Write joint coordinates ``q`` (F, D) at ``time`` (F,) seconds to ``path`` atomically,
    numbers to ``digits`` significant digits; returns the path."""
    q = np.asarray(q, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] != len(DOF_NAMES) or np.shape(time) != (len(q),):
        raise MocapError(f"joint coordinates of shape (F, {len(DOF_NAMES)}) and times (F,) "
                         f"expected, got {q.shape} and {np.shape(time)}", path=path,
                         hint="pass one row of q per time, one column per DOF")
    table = np.column_stack([np.asarray(time, dtype=np.float64), q])
    number = f"%.{digits}g"
    row_format = ",".join([number] * table.shape[1])
    complete = ~np.isnan(table).any(axis=1)
    lines = [",".join(["time_s", *DOF_NAMES])]
    lines += [row_format % tuple(row) if whole else
              ",".join(number % value if value == value else "" for value in row)
              for row, whole in zip(table.tolist(), complete)]
    return atomic_write_text(path, "\n".join(lines) + "\n")
