"""JSON at the speed of big libraries: strict parsing with orjson, the RFC 8785 (JCS) form from
orjson's sorted compact text, and a quick test for NaN and infinity.

Each function gives exactly what the reference does (:func:`json.loads`, ``rfc8785.dumps``) or
declines (returns None) so that the caller uses the reference: a 5,000-entry library (71 MB) is
parsed and canonicalised in a fraction of a second instead of several seconds.
``tests/test_fastjson.py`` compares both on random documents of every kind of number.
"""

from __future__ import annotations

import gc
import math
import re
from contextlib import contextmanager
from itertools import chain

import orjson

#: Text :func:`strict_loads` leaves to the reference parser: 19 digits in a row (orjson reads
#: integers beyond 64 bits as floats, :func:`json.loads` as integers). Found by mapping every
#: byte to "0" (a digit) or " " and searching: ten times faster than a regular expression.
_LONG_DIGITS = b"0" * 19
_DIGITS_ONLY = bytes(ord("0") if ord("0") <= i <= ord("9") else ord(" ") for i in range(256))
#: A JSON string token, escapes included.
_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"')
#: orjson's number texts that ECMAScript prints otherwise (JCS uses ECMAScript's): integral
#: floats (``1.0``, ECMAScript ``1``: outside strings, ``.0`` before ``,``, ``]`` or ``}`` ends
#: one, so plain byte replacement strips it), negative zero (``-0``) and exponents ECMAScript
#: writes out (``1e-6`` is ``0.000001``; ``1e+16`` to ``1e+20`` are integers). A number follows
#: ``:``, ``,`` or ``[``.
_INTEGRAL_ENDS = (b".0,", b".0]", b".0}")
_NEGATIVE_ZERO = re.compile(rb"([:,\[])-0(?=[,\]}])")
_NEGATIVE_ZERO_ENDS = (b"-0,", b"-0]", b"-0}")
#: Exponents ECMAScript writes out: (the text orjson writes before their digits, and those
#: digits).
_EXPONENT_TEXT = re.compile(rb"[0-9]e[-+][0-9]")
_WRITTEN_OUT = ((b"e-", (b"6",)), (b"e+", (b"16", b"17", b"18", b"19", b"20")))
#: Bytes that start a UTF-8 character beyond the BMP: JCS sorts keys by UTF-16 code units,
#: orjson by code points, and the two orders differ only there.
_BEYOND_BMP = re.compile(rb"[\xf0-\xf4]")


def strict_loads(text: str | bytes):
    """The JSON data of ``text`` as :func:`json.loads` reads it, or None (the text is
    still to be read, by the reference parser) when it holds ``NaN``, ``Infinity``, a number
    beyond a double, 19 digits in a row (an integer that long, or a long fraction, which the
    reference reads exactly as well), a lone surrogate, or is no JSON at all.
    A document it returns therefore holds finite numbers only."""
    data = text.encode("utf-8", "surrogatepass") if isinstance(text, str) else text
    if _LONG_DIGITS in data.translate(_DIGITS_ONLY):
        return None
    try:
        with collection_paused():
            return orjson.loads(data)
    except orjson.JSONDecodeError:
        return None


@contextmanager
def collection_paused():
    """Python's cyclic garbage collector paused inside the block (as it was after it). Parsing
    makes millions of lists and dicts, none of them garbage, and every collection on the way
    visits those made so far: a 5,000-entry library (71 MB) parses in 0.25 s of CPU paused,
    0.7 s not (``benchmarks/library_scale.py``, load)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def all_finite(data) -> bool:
    """Whether every number in JSON ``data`` (dicts, lists, scalars) is finite: no NaN or
    ±inf. Lists of numbers, and lists of them, are summed in one call each."""
    stack = [data]
    while stack:
        value = stack.pop()
        if isinstance(value, dict):
            stack.extend(value.values())
        elif isinstance(value, list):
            if _finite_sum(value) or (value and isinstance(value[0], list)
                                      and _finite_sum(chain.from_iterable(value))):
                continue
            stack.extend(value)
        elif isinstance(value, float) and not math.isfinite(value):
            return False
    return True


def _finite_sum(values) -> bool:
    """True when ``values`` are all numbers and their sum is finite (so is each; a sum that
    overflows says False, and the caller looks at each)."""
    try:
        return math.isfinite(sum(values))
    except TypeError:                                # not numbers
        return False


def jcs_bytes(data) -> bytes | None:
    """The RFC 8785 (JCS) form of JSON ``data`` whose numbers are finite (the caller checked:
    :func:`all_finite`), or None where this cannot give it (keys beyond the BMP, integers
    beyond ±2**53, number texts inside strings that the rewrite could touch, types orjson
    refuses): the caller then uses ``rfc8785.dumps``."""
    try:
        text = orjson.dumps(data, option=orjson.OPT_SORT_KEYS | orjson.OPT_STRICT_INTEGER)
    except (TypeError, orjson.JSONEncodeError):
        return None
    if _BEYOND_BMP.search(text):
        return None
    strings = b"\x00".join(_STRING.findall(text))
    if (any(end in strings for end in (*_INTEGRAL_ENDS, *_NEGATIVE_ZERO_ENDS))
            or _EXPONENT_TEXT.search(strings)):
        return None
    for end in _INTEGRAL_ENDS:
        text = text.replace(end, end[2:])
    if any(end in text for end in _NEGATIVE_ZERO_ENDS):
        text = _NEGATIVE_ZERO.sub(rb"\g<1>0", text)
    for mark, exponents in _WRITTEN_OUT:
        if mark in text:
            text = _write_out(text, mark, exponents)
    return text


def _write_out(text: bytes, mark: bytes, exponents: tuple[bytes, ...]) -> bytes:
    """``text`` with the numbers ``d.ddd<mark><exponent>`` (``exponent`` one of
    ``exponents``) written without exponent, as ECMAScript prints 1e-6 and 1e+16 to 1e+20."""
    pieces = text.split(mark)
    out = [pieces[0]]
    for after in pieces[1:]:
        before = out[-1]
        exponent = next((e for e in exponents if after.startswith(e)
                         and not after[len(e):len(e) + 1].isdigit()), None)
        if exponent is None:
            out.append(mark + after)
            continue
        start = max(before.rfind(c, -32) for c in (b":", b",", b"[")) + 1
        mantissa = before[start:]
        sign, mantissa = (b"-", mantissa[1:]) if mantissa.startswith(b"-") else (b"", mantissa)
        first, _, rest = mantissa.partition(b".")
        power = int(exponent) * (-1 if mark == b"e-" else 1)
        written = (b"0." + b"0" * (-power - 1) + first + rest if power < 0
                   else first + rest + b"0" * (power - len(rest)))
        out[-1] = before[:start] + sign + written
        out.append(after[len(exponent):])
    return b"".join(out)
