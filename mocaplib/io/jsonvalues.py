"""Plain JSON values from results that hold numpy arrays, numpy scalars and NaN, and JSON
text read back without surprises.

:func:`json_values` is used by every JSON the package writes: the library and its sidecars
(10 significant digits), the synthetic truth files (6 decimals: µm, µrad) and the CLI's
``--json`` output (full precision). :func:`parse_json` is used by every JSON it reads.
"""

from __future__ import annotations

import json
import math

import numpy as np
import rfc8785

from . import fs_text
from .fastjson import all_finite, jcs_bytes, strict_loads

#: Integers with more digits than this are read as floats (:func:`parse_json`): no double
#: holds more than 309 digits, and Python refuses to read integers of more than 4300.
MAX_INTEGER_DIGITS = 300


class OutOfRange(float):
    """A number in a JSON text beyond a double's range (±1.8e308): read as ±inf, and marked
    so that checks can tell it from the non-standard ``Infinity`` token."""


def _number(text: str) -> float | int:
    value = float(text)
    return OutOfRange(value) if math.isinf(value) else value


def _integer(text: str) -> float | int:
    return int(text) if len(text) <= MAX_INTEGER_DIGITS else _number(text)


def parse_json(text: str | bytes, /):
    """The JSON data of ``text`` (str, or bytes of UTF-8 text: UnicodeDecodeError when they are
    not), numbers of any size read without an exception: integers of more than
    :data:`MAX_INTEGER_DIGITS` digits as floats, numbers beyond a double's range as
    :class:`OutOfRange` infinities. Raises ValueError for text that is not JSON (also when
    nested too deep to read). Text orjson reads exactly as :func:`json.loads` does is read
    by it (:func:`mocaplib.io.fastjson.strict_loads`), several times faster; bytes it reads
    are not decoded first (0.06 s on 71 MB)."""
    return parse_json_finite(text)[0]


def parse_json_finite(text: str | bytes, /) -> tuple[object, bool]:
    """:func:`parse_json`'s data of ``text`` and whether its numbers are finite for certain
    (True when orjson read it: a text with NaN, Infinity or a number beyond a double is read
    by the reference parser, and may hold them)."""
    data = strict_loads(text)
    if data is not None:
        return data, True
    if isinstance(text, bytes):
        text = text.decode("utf-8")
    try:
        return json.loads(text, parse_int=_integer, parse_float=_number), False
    except RecursionError:
        raise ValueError("JSON nested too deep to read") from None


def is_finite_number(value, /) -> bool:
    """Whether a JSON value is a finite number (not null, a bool or a string)."""
    return (isinstance(value, (int, float)) and not isinstance(value, bool)
            and math.isfinite(value))


def float_or_nan(value, /) -> float:
    """A JSON number as a float, NaN for null (None): the reverse of :func:`json_values`."""
    return math.nan if value is None else float(value)


def json_values(obj, /, *, decimals: int | None = None, significant: int | None = None):
    """``obj`` as plain JSON values: dict (string keys), list, str, bool, int, float, None.

    numpy arrays and tuples become lists and numpy scalars Python ones; NaN and ±inf become
    None (JSON null); text UTF-8 cannot encode (an undecodable file name) goes through
    :func:`mocaplib.io.fs_text`. Floats are kept as they are, or rounded to ``decimals`` decimal places
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
    if isinstance(obj, str):
        return fs_text(obj)
    if obj is None:
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


def canonical_sha256(data, /) -> str:
    """SHA-256 (hex) of the canonical JSON text of ``data``: keys sorted, no whitespace
    (separators ``,`` and ``:``), text as it is (not ASCII-escaped), numbers as Python writes
    them (the shortest text that reads back as the same double, ``1.0`` for one), encoded as
    UTF-8. The same data read back from any formatting of the same JSON gives the same hash.
    Python's number text makes it a Python-only checksum (the build's cache); files other
    languages verify use :func:`jcs_sha256`."""
    import hashlib      # here, where hashes are taken: OpenSSL's start-up is 3 ms

    text = json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return hashlib.sha256(text.encode("utf-8", "surrogatepass")).hexdigest()


def jcs_sha256(data, /, *, finite: bool = False) -> str:
    """SHA-256 (hex) of the RFC 8785 JSON Canonicalization Scheme (JCS) form of ``data``:
    keys sorted by their UTF-16 code units, no whitespace, numbers as ECMAScript prints them
    (``1`` for one, ``1e-7``, ``1e+21``), encoded as UTF-8 — the same bytes in any language
    with a JCS library (JavaScript: ``canonicalize``). Raises ValueError for data JCS cannot
    hold (NaN, ±inf, integers beyond ±2**53). The canonical bytes come from orjson where
    :func:`mocaplib.io.fastjson.jcs_bytes` can give them, from ``rfc8785`` otherwise.
    ``finite``: the caller has checked that ``data`` holds no NaN or infinity."""
    import hashlib      # here, where hashes are taken: OpenSSL's start-up is 3 ms

    if not (finite or all_finite(data)):
        raise ValueError("no RFC 8785 form: NaN or infinity")
    try:
        return hashlib.sha256(jcs_bytes(data) or rfc8785.dumps(data)).hexdigest()
    except rfc8785.CanonicalizationError as exc:
        raise ValueError(f"no RFC 8785 form: {exc}") from None
