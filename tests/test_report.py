"""rlgsim.lab.report: file names, cell formatting, and a report folder written whole (Markdown, HTML with
the figures embedded, a CSV per table and attachment)."""

from __future__ import annotations

import base64
import csv
import re

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402

from rlgsim.lab.report import Report, Table, format_value, slug  # noqa: E402


@pytest.mark.parametrize("text, expected", [
    ("-40 °C", "m40_c"), ("40 °C", "40_c"), ("stability_after@-40 °C", "stability_after_m40_c"),
    ("x −5 K", "x_m5_k"), ("g.A-g.B", "g_a_g_b"), ("run-2", "run_2"),
    ("demo_cycle-seed7002", "demo_cycle_seed7002"), ("Table 4: PSO-SVM", "table_4_pso_svm"),
    ("°/h", "h"), ("", "item"), ("***", "item"),
])
def test_slug(text, expected):
    assert slug(text) == expected
    assert re.fullmatch(r"[a-z0-9_]+", slug(text))


def test_format_value():
    assert format_value(None) == "—" and format_value(float("nan")) == "—"
    assert format_value(3) == "3" and format_value("x") == "x" and format_value(True) == "True"
    assert format_value(0.0123456) == "0.01235" and format_value(123456.7, 3) == "1.23e+05"


def test_csv_cells_of_numpy_floats_are_plain_numbers():
    import numpy as np
    t = Table("t", ["a", "b", "c"], [[np.float64(0.1) + np.float64(0.2), 1.5, np.int64(3)]])
    assert t.csv_text().splitlines()[1] == "0.30000000000000004,1.5,3"


def test_table_rejects_ragged_rows():
    with pytest.raises(ValueError, match="row .* has 1 cells, expected 2"):
        Table("t", ["a", "b"], [[1]])


def test_report_folder(tmp_path):
    rep = Report("A & B")
    rep.heading("Section <1>")
    rep.paragraph("σ = 0.002 °/h")
    rep.bullets(["one", "two"])
    rep.table(Table.from_records("Scores", [{"name": "x", "v": 0.1}, {"name": "y", "w": 2}],
                                 note="a note"))
    rep.attachment(Table("Series", ["t", "y"], [[float(i), i * 0.5] for i in range(500)],
                         csv_name="series.csv", note="long"))
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    assert rep.figure(fig, "plot") == "plot.png"
    fig, ax = plt.subplots()
    assert rep.figure(fig, "plot") == "plot_2.png"                # names never collide
    rep.verbatim("a = 1\n", title="file.toml", language="toml")
    md_path = rep.write(tmp_path)

    md = md_path.read_text()
    assert md.startswith("# A & B\n") and "## Section <1>" in md
    assert "**Scores** ([CSV](scores.csv))" in md and "*a note*" in md
    assert "| x | 0.1 | — |" in md
    # an attachment is linked and described, not shown
    assert "**Series**: [series.csv](series.csv), 500 rows × 2 columns (t, y). *long*" in md
    assert "| 499.0 |" not in md
    assert "![plot.png](plot.png)" in md and "```toml\na = 1\n```" in md
    with open(tmp_path / "scores.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert rows == [["name", "v", "w"], ["x", "0.1", ""], ["y", "", "2"]]
    with open(tmp_path / "series.csv", newline="") as f:
        series = list(csv.reader(f))
    assert len(series) == 501 and series[-1] == ["499.0", "249.5"]
    assert (tmp_path / "plot.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    html = (tmp_path / "report.html").read_text()
    assert "<title>A &amp; B</title>" in html and "Section &lt;1&gt;" in html
    imgs = re.findall(r"src='data:image/png;base64,([A-Za-z0-9+/=]+)'", html)
    assert len(imgs) == 2
    assert base64.b64decode(imgs[0]) == (tmp_path / "plot.png").read_bytes()
    assert "<a href='series.csv'>series.csv</a>" in html
    assert {p.name for p in tmp_path.iterdir()} == {            # no temporary files left
        "report.md", "report.html", "scores.csv", "series.csv", "plot.png", "plot_2.png"}


def test_an_output_folder_that_cannot_be_created_is_a_user_error(tmp_path):
    from rlgsim.ground.errors import UserInputError
    from rlgsim.lab.report import output_folder
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert output_folder(tmp_path / "a" / "b") == tmp_path / "a" / "b"
    with pytest.raises(UserInputError, match="cannot create the output folder") as err:
        output_folder(blocker / "sub")
    assert str(blocker / "sub") in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("kind", ["write_atomic", "sidecar"])
def test_a_write_that_fails_leaves_no_temporary_file_and_names_its_path(kind, tmp_path,
                                                                        monkeypatch):
    """A full disk while a report file or a sidecar is written: the error names the file
    (a write's OSError names none) and the temporary file beside it is deleted."""
    import errno
    import os
    from rlgsim.ground import recording_write
    from rlgsim.lab import report

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    module = report if kind == "write_atomic" else recording_write
    monkeypatch.setattr(module.os, "replace", full)
    target = tmp_path / ("a.csv" if kind == "write_atomic" else "a.toml")
    with pytest.raises(OSError) as caught:
        if kind == "write_atomic":
            report.write_atomic(target, "x,y\n1,2\n")
        else:
            recording_write.write_sidecar(target, {"recording": {"rate_hz": 100.0}})
    assert caught.value.errno == errno.ENOSPC and caught.value.filename == str(target)
    assert list(tmp_path.iterdir()) == []


def test_an_input_error_inside_an_atomic_write_keeps_its_file_name(tmp_path):
    """Only a write's error (no file named) or the temporary file's is relabelled as the
    target; an input read inside the block (a dataset's blocks) keeps its own name."""
    import errno
    from rlgsim.ground.atomic import atomic_file
    with pytest.raises(OSError) as caught:
        with atomic_file(tmp_path / "out.csv"):
            raise OSError(errno.EIO, "Input/output error", str(tmp_path / "in.h5"))
    assert caught.value.filename == str(tmp_path / "in.h5")
    assert list(tmp_path.iterdir()) == []
