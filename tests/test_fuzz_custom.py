"""A user's compensator (``kind = "custom"``) that misbehaves outside ``fit`` (issue 15): its
``predict`` raises, returns NaN, infinities, the wrong number of values, strings or nothing, or
its ``fit`` calls ``sys.exit(0)`` — each is one line ``rlgsim: error: ...`` naming the
compensator and what it returned, exit code 2, and no report."""

from __future__ import annotations

import pathlib

import pytest

from rlgsim.lab.cli.main import main

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEMO = (ROOT / "scenarios" / "studies" / "demo.toml").read_text()
HEAD = DEMO[: DEMO.index("[[compensator]]")]
TAIL = DEMO[DEMO.index("[metrics]"):]

MODEL = '''
import sys
import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin


class Base(RegressorMixin, BaseEstimator):
    def fit(self, X, y):
        self.n_ = 1
        return self


class Raises(Base):
    def predict(self, X):
        raise RuntimeError("predict is not written yet")


class NaNs(Base):
    def predict(self, X):
        return np.full(np.asarray(X).shape[0], np.nan)


class Infs(Base):
    def predict(self, X):
        out = np.zeros(np.asarray(X).shape[0])
        out[1] = np.inf
        return out


class Short(Base):
    def predict(self, X):
        return np.zeros(np.asarray(X).shape[0] - 1)


class Strings(Base):
    def predict(self, X):
        return ["a"] * np.asarray(X).shape[0]


class Nothing(Base):
    def predict(self, X):
        return None


class Matrix(Base):
    def predict(self, X):
        return np.zeros((np.asarray(X).shape[0], 2))


class ExitsInFit(Base):
    def fit(self, X, y):
        sys.exit(0)

    def predict(self, X):
        return np.zeros(np.asarray(X).shape[0])


class Column(Base):
    """A column vector is a fine prediction (scikit-learn models may return one)."""
    def predict(self, X):
        return np.zeros((np.asarray(X).shape[0], 1))
'''

STUDY = HEAD + '''
[[compensator]]
name = "mine"
kind = "custom"
estimator = "my_model.py:{cls}"
inputs = ["T"]

''' + TAIL


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """One study folder whose datasets (data/) are simulated once and reused by every case."""
    root = tmp_path_factory.mktemp("custom")
    (root / "my_model.py").write_text(MODEL)
    (root / "ok.toml").write_text(STUDY.replace("{cls}", "Column"))
    assert main(["study", str(root / "ok.toml"), "-o", str(root / "out"), "-q"]) == 0
    return root


@pytest.mark.parametrize("cls,needle", [
    ("Raises", "RuntimeError: predict is not written yet"),
    ("NaNs", "NaN"),
    ("Infs", "infinite"),
    ("Short", "values for"),
    ("Strings", "not numbers"),
    ("Nothing", "not numbers"),
    ("Matrix", "values for"),
    ("ExitsInFit", "sys.exit(0)"),
])
def test_misbehaving_custom_compensator_is_one_line(folder, capsys, cls, needle):
    study = folder / f"{cls}.toml"
    study.write_text(STUDY.replace("{cls}", cls))
    out = folder / "out"
    (out / "report.md").unlink(missing_ok=True)
    capsys.readouterr()
    code = main(["study", str(study), "-o", str(out), "-q"])
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("rlgsim: error: "), err
    assert "'mine'" in lines[0] and needle in lines[0], lines[0]
    assert "Traceback" not in err
    assert not (out / "report.md").exists()
