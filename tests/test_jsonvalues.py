"""The one JSON value cleaner used by the library, the synthetic truth files and the CLI."""

import json
import math

import numpy as np
import pytest

from mocaplib.io.jsonvalues import json_values


def test_numpy_values_become_plain_python_ones():
    data = {1: np.arange(3), "t": (np.float32(0.5), np.int64(7), np.bool_(True)),
            "m": np.eye(2), "z": np.array(2.5), "s": "x", "n": None, "b": False}
    out = json_values(data)
    assert out == {"1": [0, 1, 2], "t": [0.5, 7, True], "m": [[1.0, 0.0], [0.0, 1.0]],
                   "z": 2.5, "s": "x", "n": None, "b": False}
    assert type(out["t"][1]) is int and type(out["t"][2]) is bool  # not 7.0, not 1
    json.dumps(out, allow_nan=False)  # plain values only: the encoder needs no help


def test_non_finite_floats_become_null():
    assert json_values([math.nan, np.inf, -np.inf, np.float64(np.nan)]) == [None] * 4


def test_full_precision_by_default():
    assert json_values(0.1 + 0.2) == 0.30000000000000004


def test_decimals_round_and_never_write_minus_zero():
    out = json_values([1.23456789, -1e-9, np.float64(-0.0)], decimals=6)
    assert out == [1.234568, 0.0, 0.0]
    assert json.dumps(out) == "[1.234568, 0.0, 0.0]"  # -1e-9 rounds to 0.0, not -0.0


def test_significant_digits():
    assert json_values([123456.789, 1.23456789e-12], significant=4) == [123500.0, 1.235e-12]


def test_decimals_and_significant_together_are_refused():
    with pytest.raises(ValueError, match="decimals=2 or significant=3, not both"):
        json_values([1.23456], decimals=2, significant=3)


def test_other_types_are_refused():
    with pytest.raises(TypeError, match="a set is not a JSON value"):
        json_values({"x": {1, 2}})
