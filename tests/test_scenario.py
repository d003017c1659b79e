"""Scenario loader: every user mistake is one clear UserInputError (CLI: one line, exit 2).

Property-based (hypothesis): malformed TOML text and malformed values in every place of a valid
scenario either load or raise UserInputError naming the file — never another exception.
"""

from __future__ import annotations

import copy
import pathlib
import tomllib

import h5py
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rlgsim.sim import presets
from rlgsim.lab.cli.main import format_error, main
from rlgsim.ground.errors import UserInputError
from rlgsim.sim.run.scenario import Scenario, load_scenario, parse_scenario

ROOT = pathlib.Path(__file__).resolve().parents[1]
QUICKSTART = ROOT / "scenarios" / "quickstart.toml"
BASE = tomllib.loads(QUICKSTART.read_text())
SOURCE = "test.toml"


from scenario_helpers import to_toml  # noqa: E402


def _paths(d, prefix=()):
    """Every (path) to a leaf or table in a nested dict/list."""
    if isinstance(d, dict):
        for k, v in d.items():
            yield prefix + (k,)
            yield from _paths(v, prefix + (k,))
    elif isinstance(d, list):
        for i, v in enumerate(d):
            yield prefix + (i,)
            yield from _paths(v, prefix + (i,))


PATHS = list(_paths(BASE))


def _set(d, path, value):
    d = copy.deepcopy(d)
    node = d
    for p in path[:-1]:
        node = node[p]
    node[path[-1]] = value
    return d


def _delete(d, path):
    d = copy.deepcopy(d)
    node = d
    for p in path[:-1]:
        node = node[p]
    del node[path[-1]]
    return d


def _load(d: dict) -> Scenario:
    return parse_scenario(to_toml(d), SOURCE, base_dir=ROOT / "scenarios")


def _clear_error(exc: UserInputError) -> str:
    line = format_error(exc)
    assert line.startswith("rlgsim: error: ") and "\n" not in line
    assert SOURCE in line or "unknown device" in line or "thermal preset" in line, line
    return line


# --------------------------------------------------------------------------- properties

toml_values = st.recursive(
    st.booleans() | st.integers(min_value=-2**63, max_value=2**63 - 1)
    | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=12),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner,
                                                                max_size=3),
    max_leaves=6,
)


def test_the_base_scenario_loads():
    sc = _load(BASE)
    assert sc.name == "quickstart" and sc.duration_s == 7200.0


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(text=st.text(max_size=300))
def test_arbitrary_text_never_tracebacks(text):
    try:
        parse_scenario(text, SOURCE)
    except UserInputError as exc:
        _clear_error(exc)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_corrupted_toml_syntax_reports_the_line(data):
    text = to_toml(BASE)
    pos = data.draw(st.integers(0, len(text)))
    junk = data.draw(st.sampled_from(["=", "[", "]", "\"", "{", "= =", "[[x]]\n[[x]", "\\"]))
    bad = text[:pos] + junk + text[pos:]
    try:
        tomllib.loads(bad)
    except tomllib.TOMLDecodeError:
        with pytest.raises(UserInputError, match=r"test\.toml: line \d+.*TOML syntax error"):
            parse_scenario(bad, SOURCE)
    else:
        try:
            parse_scenario(bad, SOURCE)
        except UserInputError as exc:
            _clear_error(exc)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(path=st.sampled_from(PATHS), value=toml_values)
def test_any_value_anywhere_loads_or_is_a_clear_error(path, value):
    try:
        _load(_set(BASE, path, value))
    except UserInputError as exc:
        _clear_error(exc)


@settings(max_examples=100, deadline=None)
@given(path=st.sampled_from(PATHS))
def test_any_key_removed_loads_or_is_a_clear_error(path):
    try:
        _load(_delete(BASE, path))
    except UserInputError as exc:
        _clear_error(exc)




def _get(d, path):
    for p in path:
        d = d[p]
    return d


TABLE_PATHS = [()] + [p for p in PATHS if isinstance(_get(BASE, p), dict)]


@settings(max_examples=100, deadline=None)
@given(where=st.sampled_from(TABLE_PATHS),
       key=st.from_regex(r"[a-z][a-z_]{0,15}", fullmatch=True), value=toml_values)
def test_unknown_keys_are_rejected_by_name(where, key, value):
    table = _get(BASE, where) if where else BASE
    if key in table:
        return
    with pytest.raises(UserInputError) as info:
        _load(_set(BASE, where + (key,), value))
    line = _clear_error(info.value)
    assert key in line


# --------------------------------------------------------------------------- named mistakes


def _error(d: dict) -> str:
    with pytest.raises(UserInputError) as info:
        _load(d)
    return _clear_error(info.value)


def test_misspelt_key_suggests_the_right_one():
    d = _delete(BASE, ("seed",))
    d["sead"] = 3
    assert "unknown key" in _error(d) and "did you mean 'seed'" in _error(d)


def test_wrong_type_names_key_value_and_type():
    line = _error(_set(BASE, ("seed",), "abc"))
    assert "seed" in line and "expected an integer" in line and "'abc'" in line


def test_missing_unit_is_explained():
    d = _delete(BASE, ("duration_h",))
    d["duration"] = 2
    line = _error(d)
    assert "missing unit" in line and "duration_h" in line and "duration_min" in line


def test_negative_duration_is_rejected():
    line = _error(_set(BASE, ("duration_h",), -1.0))
    assert "duration_h" in line and "-1" in line and "must be >" in line


def test_two_spellings_of_one_quantity_are_rejected():
    line = _error(_set(BASE, ("duration_s",), 60))
    assert "give only one of" in line


def _rate_paths(d, prefix=()):
    for p in _paths(d):
        if p[-1] == "rate_c_per_min" and p[0] == "chamber":
            yield p


def test_ramp_rate_zero_is_rejected():
    path = next(_rate_paths(BASE))
    line = _error(_set(BASE, path, 0.0))
    assert "rate_c_per_min" in line and "0" in line


def test_thermal_step_must_tile_a_block():
    d = copy.deepcopy(BASE)
    d.setdefault("acquisition", {})["thermal_step_s"] = 7.0
    line = _error(d)
    assert "thermal_step_s" in line and "7" in line and "600" in line


def test_power_off_before_on_is_rejected():
    d = _set(BASE, ("power",), {"on_at_min": 10, "off_at_min": 5})
    line = _error(d)
    assert "off_at_min" in line and "after power-on" in line


def test_unknown_device_name_lists_the_shipped_ones():
    line = _error(_set(BASE, ("device",), "rlg8_03"))
    assert "unknown device preset 'rlg8_03'" in line and "did you mean 'rlg8_003'" in line


def test_toml_syntax_error_names_file_and_line(tmp_path):
    p = tmp_path / "broken.toml"
    p.write_text('name = "x"\nseed = \n')
    with pytest.raises(UserInputError, match=r"broken\.toml: line 2, column \d+: TOML syntax"):
        load_scenario(str(p))


def test_shipped_scenarios_all_load():
    names = presets.list_names("scenario")
    assert "quickstart" in names
    for name in names:
        sc = load_scenario(name)
        assert sc.duration_s > 0 and sc.device.name


def test_scenario_paths_resolve_device_paths_relative_to_the_file(tmp_path):
    dev = tmp_path / "devs" / "mine.toml"
    dev.parent.mkdir()
    dev.write_text((ROOT / "scenarios" / "devices" / "rlg8_003.toml").read_text()
                   .replace('name = "rlg8_003"', 'name = "mine"'))
    sc = tmp_path / "s.toml"
    sc.write_text(to_toml(_set(BASE, ("device",), "devs/mine.toml")))
    assert load_scenario(str(sc)).device.name == "mine"


# --------------------------------------------------------------------------- through the CLI


@pytest.mark.parametrize("mutate, expected", [
    (lambda d: _set(d, ("sead",), 1), "did you mean 'seed'"),
    (lambda d: _set(d, ("seed",), "x"), "expected an integer"),
    (lambda d: _set(_delete(d, ("duration_h",)), ("duration",), 1), "missing unit"),
    (lambda d: _set(d, ("duration_h",), -5), "must be >"),
    (lambda d: _set(d, next(_rate_paths(d)), 0), "rate_c_per_min"),
])
def test_cli_reports_scenario_mistakes_in_one_line(tmp_path, capsys, mutate, expected):
    p = tmp_path / "bad.toml"
    p.write_text(to_toml(mutate(copy.deepcopy(BASE))))
    assert main(["run", str(p), "-o", str(tmp_path / "o.h5"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rlgsim: error: ") and err.count("\n") == 1
    assert str(p) in err and expected in err
    assert not (tmp_path / "o.h5").exists()


def test_cli_unknown_scenario_name(capsys):
    assert main(["run", "paper999"]) == 2
    assert "unknown scenario 'paper999'" in capsys.readouterr().err


def test_cli_unwritable_output(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["run", "quickstart", "-o", str(blocker / "x.h5"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "cannot write" in err and str(blocker) in err and err.count("\n") == 1


def test_cli_not_an_rlgsim_dataset(tmp_path, capsys):
    p = tmp_path / "other.h5"
    with h5py.File(p, "w") as f:
        f["x"] = [1, 2, 3]
    assert main(["info", str(p)]) == 2
    err = capsys.readouterr().err
    assert "not an rlgsim dataset" in err and str(p) in err and err.count("\n") == 1


# --------------------------------------------------------------------------- device presets

DEVICE = tomllib.loads((ROOT / "scenarios" / "devices" / "rlg8_003.toml").read_text())
DEVICE_PATHS = list(_paths(DEVICE))


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(path=st.sampled_from(DEVICE_PATHS), value=toml_values)
def test_any_value_in_a_device_preset_loads_or_is_a_clear_error(tmp_path, path, value):
    dev = tmp_path / "dev.toml"
    dev.write_text(to_toml(_set(DEVICE, path, value)))
    try:
        _load(_set(BASE, ("device",), str(dev)))
    except UserInputError as exc:
        line = format_error(exc)
        assert "\n" not in line and str(dev) in line, line


THERMAL = tomllib.loads((ROOT / "scenarios" / "thermal" / "rlg_single.toml").read_text())
THERMAL_PATHS = list(_paths(THERMAL))


@settings(max_examples=100, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(path=st.sampled_from(THERMAL_PATHS), value=toml_values)
def test_any_value_in_a_thermal_preset_loads_or_is_a_clear_error(tmp_path, path, value):
    thermal = tmp_path / "thermal.toml"
    thermal.write_text(to_toml(_set(THERMAL, path, value)))
    dev = tmp_path / "dev.toml"
    dev.write_text(to_toml(_set(DEVICE, ("device", "thermal_preset"), str(thermal))))
    try:
        _load(_set(BASE, ("device",), str(dev)))
    except UserInputError as exc:
        line = format_error(exc)
        assert "\n" not in line and (str(thermal) in line or str(dev) in line), line
