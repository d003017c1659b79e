"""A user's own compensator in a study (kind = "custom"): loaded from a file next to the study
or from an importable module, scored like the built-in ones; every mistake is one line."""

from __future__ import annotations

import csv
import pathlib

import pytest

from rlgsim.ground.errors import UserInputError
from rlgsim.lab.study import load_study, run_study

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEMO = (ROOT / "scenarios" / "studies" / "demo.toml").read_text()
HEAD = DEMO[: DEMO.index("[[compensator]]")]
TAIL = DEMO[DEMO.index("[metrics]"):]

MODEL = '''
import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin


class CubicInFirstInput(RegressorMixin, BaseEstimator):
    """A user's compensator: a cubic polynomial of the first input."""

    def __init__(self, degree=3):
        self.degree = degree

    def fit(self, X, y):
        X = np.asarray(X, float)
        self.coef_ = np.polyfit(X[:, 0], np.asarray(y, float), self.degree)
        return self

    def predict(self, X):
        return np.polyval(self.coef_, np.asarray(X, float)[:, 0])


class Broken(RegressorMixin, BaseEstimator):
    def fit(self, X, y):
        raise RuntimeError("my model is not finished")

    def predict(self, X):
        return np.zeros(len(X))


class NoPredict:
    def get_params(self, deep=True):
        return {}

    def fit(self, X, y):
        return self
'''

CUSTOM = '''
[[compensator]]
name = "mine"
kind = "custom"
estimator = "my_model.py:CubicInFirstInput"
inputs = ["T"]
params = { degree = 3 }

[[compensator]]
name = "LS cubic T"
kind = "polynomial"
inputs = ["T"]
params = { degree = 3 }

[[compensator]]
name = "sklearn ridge"
kind = "custom"
estimator = "sklearn.linear_model:Ridge"
inputs = ["T", "dT/dt", "U"]
params = { alpha = 1e-6 }

'''


def _study(folder: pathlib.Path, compensators: str = CUSTOM) -> pathlib.Path:
    (folder / "my_model.py").write_text(MODEL)
    path = folder / "mine.toml"
    path.write_text(HEAD + compensators + TAIL)
    return path


def _scores(folder: pathlib.Path) -> dict[str, dict[str, float]]:
    with open(folder / "scores_demo_cycle_seed7002.csv", newline="") as f:
        return {r["compensator"]: {k: float(v) for k, v in r.items() if k != "compensator" and v}
                for r in csv.DictReader(f)}


def test_custom_estimators_are_fitted_and_scored_like_the_built_in_ones(tmp_path):
    study = load_study(str(_study(tmp_path)))
    run_study(study, tmp_path / "out", progress=False)
    sc = _scores(tmp_path / "out")
    # the user's cubic and the built-in cubic least squares are the same model
    for key in ("stability_after", "rmse_true", "resid_std_true", "law_resid_std"):
        assert sc["mine"][key] == pytest.approx(sc["LS cubic T"][key], rel=1e-6)
    assert sc["sklearn ridge"]["stability_after"] < sc["raw"]["stability_after"]
    md = (tmp_path / "out" / "report.md").read_text()
    assert "mine" in md and "sklearn ridge" in md


@pytest.mark.parametrize("old, new, expected", [
    ('estimator = "my_model.py:CubicInFirstInput"', 'estimator = "my_model.py"',
     "give 'package.module:Class'"),
    ('estimator = "my_model.py:CubicInFirstInput"', 'estimator = "nofile.py:X"',
     "nofile.py' not found"),
    ('estimator = "my_model.py:CubicInFirstInput"', 'estimator = "my_model.py:Nothing"',
     "has no class 'Nothing'"),
    ('estimator = "my_model.py:CubicInFirstInput"', 'estimator = "my_model.py:NoPredict"',
     "lacks predict"),
    ('estimator = "sklearn.linear_model:Ridge"', 'estimator = "no_such_pkg.mod:Ridge"',
     "cannot import 'no_such_pkg.mod'"),
    ('params = { degree = 3 }\n\n[[compensator]]\nname = "LS',
     'params = { degre = 3 }\n\n[[compensator]]\nname = "LS', "params.degre: unknown key"),
    ('kind = "polynomial"', 'kind = "polynomial"\nestimator = "x:Y"', "only with kind"),
    ('estimator = "sklearn.linear_model:Ridge"\n', "", 'needs estimator ='),
])
def test_mistakes_with_custom_estimators_are_one_line_user_errors(old, new, expected, tmp_path):
    assert old in CUSTOM
    path = _study(tmp_path, CUSTOM.replace(old, new, 1))
    with pytest.raises(UserInputError, match="mine.toml") as err:
        load_study(str(path))
    assert expected in str(err.value) and "\n" not in str(err.value)


def test_an_exception_in_the_users_fit_is_a_user_error_naming_the_compensator(tmp_path):
    path = _study(tmp_path, CUSTOM.replace("my_model.py:CubicInFirstInput", "my_model.py:Broken")
                  .replace("params = { degree = 3 }\n\n[[compensator]]\nname = \"LS",
                           "\n[[compensator]]\nname = \"LS", 1))
    study = load_study(str(path))
    with pytest.raises(UserInputError, match="'mine' .*RuntimeError: my model is not finished"):
        run_study(study, tmp_path / "out", progress=False)
    assert not (tmp_path / "out" / "report.md").exists()
