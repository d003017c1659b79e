"""benchmarks/compare_outputs.py: the byte-identity check of two builds' outputs (issue 24).

Two folders written by different checkouts must compare equal when only the scenario's path
and the run times differ, and unequal when one number, string or table cell does.
"""

from __future__ import annotations

import importlib.util
import pathlib

import h5py
import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("compare_outputs",
                                              ROOT / "benchmarks" / "compare_outputs.py")
compare_outputs = importlib.util.module_from_spec(spec)
spec.loader.exec_module(compare_outputs)


def _write(folder: pathlib.Path, source: str, wall_s: str, value: float = 1.5,
           label: str = "soak") -> pathlib.Path:
    folder.mkdir()
    with h5py.File(folder / "run.h5", "w") as f:
        f.attrs["scenario_source"] = source
        f.attrs["seed"] = 7
        time = f.create_dataset("probes/time", data=np.arange(3.0))
        time.make_scale("time")
        temperature = f.create_dataset("probes/temperature", data=np.array([20.0, value, 21.0]))
        temperature.dims[0].attach_scale(time)
        f.create_dataset("timeline/label", data=np.array([label], dtype=h5py.string_dtype()))
    (folder / "scores.csv").write_text(f"method,rmse_deg_per_h,wall_s\nLS,0.0123,{wall_s}\n")
    (folder / "report.md").write_text(f"**Scores**\n\n| method | rmse |\n|---|---|\n| LS | 0.0123 |\n\n"
                                      f"| step | wall time |\n|---|---|\n| fit | {wall_s} |\n\n"
                                      f"**Wall time**\n\n| step | s |\n|---|---|\n| fit | {wall_s} |\n")
    return folder


def test_outputs_of_two_checkouts_compare_equal(tmp_path, capsys):
    a = _write(tmp_path / "a", "/one/checkout/scenarios/x.toml", "1.25")
    b = _write(tmp_path / "b", "/another/scenarios/x.toml", "9.75")
    assert compare_outputs.compare(a, b) == 0
    assert "3 files compared" in capsys.readouterr().out


@pytest.mark.parametrize("change", [{"value": 1.5000000000000002}, {"label": "ramp"}])
def test_a_changed_number_or_string_in_a_dataset_is_found(tmp_path, change):
    a = _write(tmp_path / "a", "/x.toml", "1")
    b = _write(tmp_path / "b", "/x.toml", "1", **change)
    assert compare_outputs.compare(a, b) == 1


def test_a_changed_table_cell_and_a_missing_file_are_found(tmp_path):
    a = _write(tmp_path / "a", "/x.toml", "1")
    b = _write(tmp_path / "b", "/x.toml", "1")
    (b / "scores.csv").write_text("method,rmse_deg_per_h,wall_s\nLS,0.0124,1\n")
    (b / "report.md").unlink()
    assert compare_outputs.compare(a, b) == 2


def test_a_changed_cell_of_a_captioned_markdown_table_is_found(tmp_path):
    a = _write(tmp_path / "a", "/x.toml", "1")
    b = _write(tmp_path / "b", "/x.toml", "1")
    (b / "report.md").write_text((b / "report.md").read_text().replace("0.0123", "0.0124"))
    assert compare_outputs.compare(a, b) == 1


def test_an_empty_folder_is_one_line_and_status_2(tmp_path, capsys):
    a = _write(tmp_path / "a", "/x.toml", "1")
    (tmp_path / "empty").mkdir()
    assert compare_outputs.main(["compare", str(a), str(tmp_path / "empty")]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_make_refuses_a_folder_that_holds_files(tmp_path, capsys):
    a = _write(tmp_path / "a", "/x.toml", "1")
    assert compare_outputs.main(["make", str(a), "--scenarios", "--studies"]) == 2
    assert "not an empty folder" in capsys.readouterr().err
    assert sorted(p.name for p in a.iterdir()) == ["report.md", "run.h5", "scores.csv"]
