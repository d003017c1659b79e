"""Reports a newcomer reads (issue 29): a study of one's own (no ``paper`` key, no published
numbers) shows no paper columns nor a paper's claims; Monte Carlo metrics carry units."""

from __future__ import annotations

import re

from rlgsim.lab.cli.main import main

OWN = """\
[study]
name = "mine"
description = "my gyro, my cycle"
recipe = "bias_compensation"
device_seed = 1001

[data]
train = [{ scenario = "demo_cycle", seed = 7001 }]
test = [{ scenario = "demo_cycle", seed = 7002 }]
window_s = 100
gyro = "z"

[features]
temperature = "g.A"
uhfo = true

[[compensator]]
name = "LS cubic T"
kind = "polynomial"
inputs = ["T"]
params = { degree = 3 }

[[compensator]]
name = "LSSVM T, U"
kind = "lssvm"
inputs = ["T", "U"]
"""


def test_own_study_has_no_paper_columns_nor_claims(tmp_path, capsys):
    (tmp_path / "mine.toml").write_text(OWN)
    assert main(["study", str(tmp_path / "mine.toml"), "-o", str(tmp_path / "out"), "-q"]) == 0
    md = (tmp_path / "out" / "report.md").read_text()
    own = md[:md.index("## Study file")]            # the embedded preset texts cite papers
    assert "(paper)" not in own and "paper 001" not in own and "published" not in own
    assert "Rankings: the paper's claims" not in own
    assert "## Scores on test run" in own
    assert re.search(r"\| compensator \| inputs \| before °/h \| after °/h \| improvement % \|",
                     own), own
    assert not list((tmp_path / "out").glob("paper_*.csv"))
    assert (tmp_path / "out" / "scores_compensators.csv").is_file()
    # provenance: every report says which versions made it
    from importlib.metadata import version
    assert md.rstrip().endswith(f"*Made with rlgsim {version('rlgsim')}, numpy "
                                f"{version('numpy')}, scipy {version('scipy')}, h5py "
                                f"{version('h5py')}, numba {version('numba')}.*")
    assert "Made with rlgsim" in (tmp_path / "out" / "report.html").read_text()
