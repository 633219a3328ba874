"""The fast JSON paths give what the reference implementations give: orjson's parse what
:func:`json.loads` reads, the canonical bytes what ``rfc8785`` writes (RFC 8785), on random
documents with numbers of every magnitude and strings of every kind; where they cannot, they
decline and the reference is used."""

from __future__ import annotations

import gc
import json
import math

import numpy as np
import orjson
import pytest
import rfc8785

from mocaplib.io.fastjson import all_finite, collection_paused, jcs_bytes, strict_loads
from mocaplib.io.jsonvalues import jcs_sha256, parse_json


def random_document(rng: np.random.Generator, n: int = 400) -> dict:
    """Numbers from 1e-9 to 1e22 (the ranges where ECMAScript's and orjson's texts differ:
    integral floats, 1e-6, 1e+16 to 1e+20), negative zero, integers, strings with control
    characters, digits and JSON punctuation, nested lists."""
    magnitudes = 10.0 ** rng.integers(-9, 23, n)
    floats = (rng.choice([-1, 1], n) * magnitudes
              * rng.choice([1.0, 1.5, 1.234567891, 7.0], n)).tolist()
    floats += [0.0, -0.0, 1.0, -2.0, 1e-6, 1.5e-6, 1e-7, 1e16, 1e20, 1e21, 123456789.0]
    strings = ["plain", "tab\there", "ctl\x01\x1f", "quote\"back\\", "a,1.0]", "x:-0,",
               "é ü", "line\u2028sep", "v 0.1.0", "[1e-6,"]
    return {"floats": floats, "ints": rng.integers(-2**53, 2**53, 20).tolist(),
            "rows": [floats[i:i + 7] for i in range(0, 70, 7)],
            "strings": strings, "nested": {s: [i, None, True, {"k": f}] for i, (s, f)
                                           in enumerate(zip(strings, floats))}}


@pytest.mark.parametrize("seed", range(5))
def test_canonical_bytes_are_rfc8785s(seed):
    document = random_document(np.random.default_rng(seed))
    fast = jcs_bytes(document)
    if fast is None:   # a string held a number-like text: declined, the reference is used
        fast = jcs_bytes({k: v for k, v in document.items() if k not in ("strings", "nested")})
        document = {k: v for k, v in document.items() if k not in ("strings", "nested")}
    assert fast is not None
    assert fast == rfc8785.dumps(document)



@pytest.mark.parametrize("seed", range(5))
def test_canonical_bytes_around_escaped_strings_are_rfc8785s(seed):
    """Strings with escaped quotes and backslashes (the rewrite tells strings from numbers by
    the quotes), beside numbers to rewrite, and numbers alone at the text's start and end."""
    document = random_document(np.random.default_rng(seed))
    del document["strings"], document["nested"]
    document["escaped"] = ['a\\', '\\"', 'x\\\\"y', '"', "\\\\", 'ab"c\\', "é"]
    document['k"\\'] = [1.0, -0.0, 1e-6, -1.5e-6, 1e16, 2.5e20]
    assert jcs_bytes(document) == rfc8785.dumps(document)
    for alone in (1.0, -0.0, 1e-6, -1.5e-6, 1e16, 2.5e20, 1e21, 0.5, [1.0], [-0.0, 2.0],
                  {"a": 1.5e-6, "b": "x" * 40}, [-2.5e-6, 3e16, "y" * 40]):
        assert jcs_bytes(alone) == rfc8785.dumps(alone), alone

def test_canonical_bytes_decline_what_they_cannot_write():
    assert jcs_bytes({"\U0001f600": 1, "\ue000": 2}) is None     # keys sorted by UTF-16 units
    assert jcs_bytes({"n": 2**53 + 1}) is None                    # beyond JCS's integers
    assert jcs_bytes({"s": "a,1.0,b"}) is None                    # a number text in a string
    with pytest.raises(ValueError, match="NaN or infinity"):
        jcs_sha256({"x": [1.0, math.nan]})


def test_strict_parse_is_json_loads_or_declines():
    document = random_document(np.random.default_rng(7))
    document["floats"] = [float(f"{x:.10g}") for x in document["floats"]]  # as libraries hold
    text = json.dumps(document)
    assert strict_loads(text) == json.loads(text)
    for declined in ('{"x": NaN}', '[Infinity]', "[1e400]", "[12345678901234567890123]",
                     '["\\ud800"]', "[1,", "[0.00015000000000000001]"):
        assert strict_loads(declined) is None, declined
    # the reference parser then reads them as before: a 23-digit integer stays an integer
    assert parse_json("[12345678901234567890123]") == [12345678901234567890123]


def test_all_finite_finds_nan_and_infinity_anywhere():
    document = random_document(np.random.default_rng(3))
    assert all_finite(document)
    for path in (("floats", 5), ("rows", 3, 2), ("nested", "plain", 3, "k")):
        for bad in (math.nan, math.inf, -math.inf):
            changed = json.loads(json.dumps(document))
            holder = changed
            for key in path[:-1]:
                holder = holder[key]
            holder[path[-1]] = bad
            assert not all_finite(changed), (path, bad)
    assert all_finite({"big": [1e308, 1e308]})   # the sum overflows, each number is finite


def test_collection_paused_restores_the_collectors_state():
    assert gc.isenabled()
    with pytest.raises(orjson.JSONDecodeError):
        with collection_paused():
            assert not gc.isenabled()
            orjson.loads(b"[1,")
    assert gc.isenabled()
    assert strict_loads(b"[1, 2]") == [1, 2] and gc.isenabled()
    gc.disable()
    try:
        with collection_paused():
            pass
        assert not gc.isenabled()      # left as it was: disabled
    finally:
        gc.enable()


def test_parse_json_reads_utf8_bytes_as_their_text():
    text = '{"é": [1.5, NaN], "n": 12345678901234567890123}'
    for given in ('{"é": [1.5, 2]}', text):
        assert repr(parse_json(given.encode("utf-8"))) == repr(parse_json(given))
    for other in ("latin-1", "utf-16"):       # bytes are UTF-8 or refused
        with pytest.raises(UnicodeDecodeError):
            parse_json('{"é": 1, "x": NaN}'.encode(other))
