"""Plain JSON values from results that hold numpy arrays, numpy scalars and NaN.

One helper, :func:`json_values`, used by every JSON the package writes: the library and its
sidecars (10 significant digits), the synthetic truth files (6 decimals: µm, µrad) and the
CLI's ``--json`` output (full precision).
"""

from __future__ import annotations

import math

import numpy as np


def json_values(obj, /, *, decimals: int | None = None, significant: int | None = None):
    """``obj`` as plain JSON values: dict (string keys), list, str, bool, int, float, None.

    numpy arrays and tuples become lists and numpy scalars Python ones; NaN and ±inf become
    None (JSON null). Floats are kept as they are, or rounded to ``decimals`` decimal places
    (a value rounded to zero is written 0.0, never -0.0) or to ``significant`` significant
    digits (not both: ValueError). Raises TypeError for any other type.
    """
    if decimals is not None and significant is not None:
        raise ValueError(f"round to decimals={decimals} or significant={significant}, not both")
    if isinstance(obj, dict):
        return {str(k): json_values(v, decimals=decimals, significant=significant)
                for k, v in obj.items()}
    if isinstance(obj, np.ndarray):
        obj = obj.tolist()
    if isinstance(obj, (list, tuple)):
        return [json_values(v, decimals=decimals, significant=significant) for v in obj]
    if obj is None or isinstance(obj, str):
        return obj
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        value = float(obj)
        if not math.isfinite(value):
            return None
        if decimals is not None:
            return round(value, decimals) + 0.0
        if significant is not None:
            return float(format(value, f".{significant}g"))
        return value
    raise TypeError(f"a {type(obj).__name__} is not a JSON value")
