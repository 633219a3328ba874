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

import numpy as np
import orjson

#: Text :func:`strict_loads` leaves to the reference parser: 19 digits in a row (orjson reads
#: integers beyond 64 bits as floats, :func:`json.loads` as integers). Found by mapping every
#: byte to "0" (a digit) or " " and searching: ten times faster than a regular expression.
_LONG_DIGITS = b"0" * 19
_DIGITS_ONLY = bytes(ord("0") if ord("0") <= i <= ord("9") else ord(" ") for i in range(256))
#: orjson's number texts that ECMAScript prints otherwise (JCS uses ECMAScript's), outside
#: strings: integral floats (``1.0``, ECMAScript ``1``: ``.0`` followed by the end of a number,
#: one of :data:`_NUMBER_ENDS`), negative zero (``-0``, after a number's start, one of
#: :data:`_NUMBER_STARTS`) and exponents ECMAScript writes out (``1e-6`` is ``0.000001``;
#: ``1e+16`` to ``1e+20`` are integers: :data:`_WRITTEN_OUT_POWERS`).
_NUMBER_ENDS, _NUMBER_STARTS = b",]}", b":,["
_WRITTEN_OUT_POWERS = (-6, 16, 17, 18, 19, 20)
_DIGITS = np.frombuffer(b"0123456789", dtype=np.uint8)
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
            rows = value and isinstance(value[0], list)
            if _finite_sum(chain.from_iterable(value) if rows else value):
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
    refuses): the caller then uses ``rfc8785.dumps``.

    orjson's sorted compact text with ECMAScript's number forms put back: the bytes to change
    are found with numpy over the whole text (a string's bytes lie between an odd and an even
    unescaped quote), the integral floats' ``.0`` and the negative zeros' ``-`` dropped in one
    pass, and the few exponents ECMAScript writes out rewritten one by one."""
    try:
        text = orjson.dumps(data, option=orjson.OPT_SORT_KEYS | orjson.OPT_STRICT_INTEGER)
    except (TypeError, orjson.JSONEncodeError):
        return None
    if not text.isascii() and _BEYOND_BMP.search(text):
        return None
    # a number at the text's end is followed by, and one at its start (index -1) preceded
    # by, the comma appended
    codes = np.frombuffer(text + b",", dtype=np.uint8)
    scratch = np.empty(len(codes), dtype=bool)      # one buffer for every full-text test
    quotes = _unescaped_quotes(codes, scratch)
    integral = _pairs(codes, b".0", scratch)
    negative_zero = _pairs(codes, b"-0", scratch)
    exponents = _exponents(codes, scratch)
    ends = _codes(_NUMBER_ENDS)
    keep = scratch
    keep.fill(True)
    keep[-1] = False
    integral = integral[np.isin(codes[integral + 2], ends)]
    keep[integral] = keep[integral + 1] = False
    # "-0" then an end, or then an integral's ".0"
    negative_zero = negative_zero[(np.isin(codes[negative_zero + 2], ends)
                                   | ~keep[negative_zero + 2])
                                  & np.isin(codes[negative_zero - 1], _codes(_NUMBER_STARTS))]
    keep[negative_zero] = False
    if any(_inside_strings(quotes, at).any() for at in (integral, negative_zero, exponents)):
        return None
    canonical = codes[keep].tobytes()
    exponents, powers = _written_out(codes, exponents)
    if not len(exponents):
        return canonical
    # each exponent's position in the canonical text: less the bytes dropped before it
    shift = 2 * np.searchsorted(integral, exponents) + np.searchsorted(negative_zero, exponents)
    return _write_out(canonical, (exponents - shift).tolist(), powers.tolist())


def _codes(text: bytes) -> np.ndarray:
    """The bytes of ``text`` as a uint8 array (N,), without copying."""
    return np.frombuffer(text, dtype=np.uint8)


def _positions(codes: np.ndarray, byte: int, scratch: np.ndarray) -> np.ndarray:
    """Positions (K,) of ``byte`` in ``codes`` (N,) uint8; ``scratch`` (N,) bool is
    overwritten (a buffer reused: a new one per test would cost its page faults)."""
    return np.flatnonzero(np.equal(codes, byte, out=scratch))


def _pairs(codes: np.ndarray, pair: bytes, scratch: np.ndarray) -> np.ndarray:
    """Positions (K,) in ``codes`` (N,) uint8, whose last byte is no ``pair[0]``, where the
    two bytes ``pair`` start (``scratch``: :func:`_positions`)."""
    first = _positions(codes, pair[0], scratch)
    return first[codes[first + 1] == pair[1]]


def _unescaped_quotes(codes: np.ndarray, scratch: np.ndarray) -> np.ndarray:
    """Positions (K,) of the quotes that open and close strings: those after an even number
    of backslashes (``scratch``: :func:`_positions`)."""
    quotes = _positions(codes, ord('"'), scratch)
    after_backslash = quotes[codes[quotes - 1] == ord("\\")]
    escaped = []
    for q in after_backslash.tolist():
        run = 1                                     # backslashes right before the quote
        while codes[q - run - 1] == ord("\\"):
            run += 1
        if run % 2:
            escaped.append(q)
    return np.setdiff1d(quotes, escaped, assume_unique=True) if escaped else quotes


def _inside_strings(quotes: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Whether each position ``at`` (K,) lies inside a string: after an odd number of the
    unescaped ``quotes``."""
    return np.searchsorted(quotes, at) % 2 == 1


def _exponents(codes: np.ndarray, scratch: np.ndarray) -> np.ndarray:
    """Positions (K,) of the ``e`` of ``<digit>e<sign><digit>`` in ``codes`` (N,) uint8: the
    exponents of numbers, or such text in a string (``scratch``: :func:`_positions`)."""
    e = _positions(codes, ord("e"), scratch)
    e = e[(e > 0) & (e < len(codes) - 2)]
    e = e[np.isin(codes[e + 1], _codes(b"-+"))]
    return e[np.isin(codes[e - 1], _DIGITS) & np.isin(codes[e + 2], _DIGITS)]


def _written_out(codes: np.ndarray, exponents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Of the exponents' positions (K,) in ``codes`` (a comma after the text), those
    ECMAScript writes out (:data:`_WRITTEN_OUT_POWERS`), and their powers of ten."""
    digit = codes[np.minimum(exponents[:, None] + [2, 3, 4], len(codes) - 1)] - ord("0")
    digit = np.where(digit <= 9, digit.astype(int), -1)       # -1: not a digit
    negative = codes[exponents + 1] == ord("-")
    one_digit = digit[:, 1] < 0
    two_digits = (digit[:, 1] >= 0) & (digit[:, 2] < 0)
    power = np.where(negative, -digit[:, 0], 10 * digit[:, 0] + digit[:, 1])
    chosen = np.where(negative, one_digit, two_digits) & np.isin(power, _WRITTEN_OUT_POWERS)
    return exponents[chosen], power[chosen]


def _write_out(text: bytes, exponents: list[int], powers: list[int]) -> bytes:
    """``text`` with the numbers ``d.ddde<sign><digits>`` whose ``e`` is at one of
    ``exponents`` (ascending) written without exponent, as ``d.ddd`` times 10 to ``powers``
    (-6, or 16 to 20): ``0.00000dddd`` or ``dddd0…0``."""
    pieces, done = [], 0
    for e, power in zip(exponents, powers):
        lo = max(done, e - 32)                      # a number's text is shorter than that
        start = max(text.rfind(b":", lo, e), text.rfind(b",", lo, e),
                    text.rfind(b"[", lo, e), lo - 1) + 1
        negative = text[start] == ord("-")
        first, _, rest = text[start + negative:e].partition(b".")
        written = (b"0." + b"0" * (-power - 1) + first + rest if power < 0
                   else first + rest + b"0" * (power - len(rest)))
        pieces += [text[done:start], b"-" * negative, written]
        done = e + (3 if power < 0 else 4)
    return b"".join(pieces) + text[done:]
