"""The command line and the README agree: every subcommand and ``--version`` is listed;
``rlgsim --version``; a scenario path that does not exist but names a shipped one suggests it."""

from __future__ import annotations

import pathlib
import re

import pytest

from rlgsim import __version__
from rlgsim.lab.cli.main import _parser, main

README = pathlib.Path(__file__).resolve().parents[1] / "README.md"


def _subcommands() -> list[str]:
    sub = next(a for a in _parser()._actions if a.dest == "command")
    return sorted(sub.choices)


def test_readme_lists_every_subcommand_and_version():
    text = README.read_text(encoding="utf-8")
    commands = _subcommands()
    assert {"calibrate", "export", "study", "run"} <= set(commands)
    missing = [c for c in commands if not re.search(rf"^rlgsim {c}\b", text, re.M)]
    assert missing == []
    assert re.search(r"^rlgsim --version\b", text, re.M)
    assert "--export-models" in text


def test_version(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"rlgsim {__version__}"


@pytest.mark.parametrize("argv, hint", [
    (["run", "nowhere/demo_cycle.toml"], "did you mean the shipped scenario 'demo_cycle'"),
    (["run", "./quickstrat.toml"], "did you mean the shipped scenario 'quickstart'"),
    (["study", "studies/paper001.toml"], "did you mean the shipped study 'paper001'"),
])
def test_missing_path_naming_a_shipped_file_suggests_it(argv, hint, capsys, tmp_path,
                                                         monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "no such file" in err and hint in err and err.count("\n") == 1


def test_missing_path_naming_nothing_shipped_has_no_hint(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "my/zzzz_qqqq.toml"]) == 2
    assert "did you mean" not in capsys.readouterr().err
