"""A study's fitted compensators written as models/<name>.json, .c, .h (sim/study_models)."""

from __future__ import annotations

import numpy as np
import pytest

from rlgsim.estimators.columns import Columns
from rlgsim.estimators.model_export import load_json
from rlgsim.lab.report import Report
from rlgsim.lab.study_models import FittedModel, input_unit, report_models, write_models


def test_input_units_of_the_study_inputs():
    assert [input_unit(n) for n in ("T", "dT/dt", "U", "A", "g.A", "A-B")] == \
        ["°C", "K/s", "V", "°C", "°C", "K"]


def test_write_models_names_files_uniquely_and_skips_custom(tmp_path):
    from sklearn.linear_model import LinearRegression

    from rlgsim.estimators.polynomial import PolynomialRegressor
    rng = np.random.default_rng(0)
    X = Columns({"T": rng.uniform(-40, 70, 50), "A-B": rng.normal(0, 0.3, 50)})
    y = 1e-3 * X["T"] + 0.01 * X["A-B"] + rng.normal(0, 1e-4, 50)
    poly = PolynomialRegressor(degree=2).fit(X, y)
    models = [FittedModel("LS (T, A-B)", "polynomial", poly, X, ("T", "A-B")),
              FittedModel("LS (T; A-B)", "polynomial", poly, X, ("T", "A-B")),
              FittedModel("mine", "custom", LinearRegression().fit(X.values, y), X, X.names)]
    records = write_models(models, tmp_path / "models")
    assert [r["JSON"] for r in records] == ["models/ls_t_a_b.json", "models/ls_t_a_b_2.json",
                                            "—"]
    assert "custom" in records[2]["note"]
    loaded = load_json(tmp_path / "models" / "ls_t_a_b.json")
    assert loaded.input_units_ == ("°C", "K") and loaded.target_unit_ == "°/h"
    np.testing.assert_array_equal(loaded.predict(X), poly.predict(X))
    assert (tmp_path / "models" / "ls_t_a_b_2.c").exists()
    rep = Report("r")
    report_models(rep, records)
    assert "models/ls_t_a_b.json" in rep.markdown()


@pytest.mark.parametrize("name", ["A-B", "gx.A-gx.B"])
def test_gradient_names_are_kelvin(name):
    assert input_unit(name) == "K"
