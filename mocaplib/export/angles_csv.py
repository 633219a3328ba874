"""Joint coordinates as CSV: a ``time_s`` column, then one column per DOF.

The header is ``time_s`` and :data:`mocaplib.skeleton.DOF_NAMES`; each row is one frame, every
number written with ``%.{digits}g`` (radians, ``pelvis_t*`` metres, seconds), NaN as an empty
field, lines ending in ``\\n``: the bytes ``pandas.DataFrame.to_csv(float_format="%.9g")``
writes for :attr:`mocaplib.model.motion.Motion.angles`, without importing pandas.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..io.atomic import atomic_write_text
from ..skeleton import DOF_NAMES

if TYPE_CHECKING:
    from ..model.motion import Motion


def write_angles_csv(motion: "Motion", path: str | os.PathLike, /, *, digits: int = 9) -> Path:
    """Write ``motion``'s joint coordinates (F, D) at its times (F,) s to ``path`` atomically,
    numbers to ``digits`` significant digits; returns the path."""
    table = np.column_stack([motion.time, motion.q])
    number = f"%.{digits}g"
    row_format = ",".join([number] * table.shape[1])
    complete = ~np.isnan(table).any(axis=1)
    lines = [",".join(["time_s", *DOF_NAMES])]
    lines += [row_format % tuple(row) if whole else
              ",".join(number % value if value == value else "" for value in row)
              for row, whole in zip(table.tolist(), complete)]
    return atomic_write_text(path, "\n".join(lines) + "\n")
