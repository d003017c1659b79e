"""rlgsim.ground.toml_text: TOML written with tomlkit reads back (tomllib) to exactly the data written;
changed keys keep the document's comments; numpy values are written as plain numbers."""

from __future__ import annotations

import copy
import math
import tomllib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rlgsim.ground.errors import UserInputError
from rlgsim.ground.toml_text import dumps, set_value, value_text, with_values

_leaves = (st.booleans() | st.integers(min_value=-2**63, max_value=2**63 - 1)
           | st.floats(allow_nan=False) | st.text(max_size=12))
_values = st.recursive(_leaves, lambda inner: st.lists(inner, max_size=3)
                       | st.dictionaries(st.text(max_size=6), inner, max_size=3), max_leaves=8)
_documents = st.dictionaries(st.text(max_size=6), _values, max_size=5)


@settings(max_examples=300, deadline=None)
@given(data=_documents)
def test_dumps_and_value_text_read_back_exactly(data):
    assert tomllib.loads(dumps(data)) == data
    for v in data.values():
        assert tomllib.loads(f"x = {value_text(v)}\n")["x"] == v


@settings(max_examples=200, deadline=None)
@given(data=_documents, key=st.from_regex(r"[a-z]{1,4}(\.[a-z]{1,4}){0,2}", fullmatch=True),
       value=_values)
def test_with_values_reads_back_as_the_changed_data(data, key, value):
    text = "# kept\n" + dumps(data)
    try:
        out = with_values(text, {key: value})
    except UserInputError as exc:                 # e.g. a key path through a scalar
        assert key in str(exc) and "\n" not in str(exc)
        return
    expected = copy.deepcopy(data)
    set_value(expected, key, value)
    assert tomllib.loads(out) == expected


def test_special_values_numpy_comments_and_inline_tables():
    data = {"a": np.float64(1.5), "n": np.int64(3), "v": np.arange(3), "f": math.inf,
            "t": {"x": 1, "conduction": {"g": 2.0}}, "l": [{"p": 1}, {"p": 2}]}
    text = dumps(data, header="fitted\nby test", inline={"conduction"},
                 comments={("a",): "se 0.1", ("t", "conduction", "g"): "se 0.2",
                           ("l", 1, "p"): "se p"})
    assert tomllib.loads(text) == {"a": 1.5, "n": 3, "v": [0, 1, 2], "f": math.inf,
                                   "t": {"x": 1, "conduction": {"g": 2.0}},
                                   "l": [{"p": 1}, {"p": 2}]}
    assert text.startswith("# fitted\n# by test\n")
    assert "a = 1.5  # se 0.1\n" in text and "conduction = {g = 2.0}  # se 0.2\n" in text
    assert "p = 2  # se p\n" in text
    assert value_text({"k": [1, "s"]}) == '{k = [1, "s"]}'
    with pytest.raises(UserInputError, match="cannot write a set value to TOML"):
        dumps({"s": {1, 2}})


def test_with_values_keeps_comments_removes_and_reports():
    text = "# head\na = 1  # note a\n\n[t]\nb = 2  # note b\n"
    out = with_values(text, {"t.b": 3, "t.c.d": [1, 2], "a": None, "n[0]": {"x": 1}})
    assert tomllib.loads(out) == {"t": {"b": 3, "c": {"d": [1, 2]}}, "n": [{"x": 1}]}
    assert "# head\n" in out and "b = 3  # note b\n" in out and "note a" not in out
    with pytest.raises(UserInputError, match=r"change 't\[2\]': no element \[2\] to set"):
        with_values("t = [1]\n", {"t[2]": 5})
    with pytest.raises(UserInputError, match="not a key path"):
        with_values(text, {"a..b": 5})
