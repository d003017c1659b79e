"""The next experiment (issue 28; src/rlgsim/lab/identify/next_experiment.py): ``identify
--suggest-programme`` on a unit whose rate and gradients the recording cannot separate writes
a scenario on the twin; simulated and identified again, the standard errors of the terms it
promised to separate shrink, and as predicted (within the noise fit's and the chamber lag's
difference from the design's assumptions)."""

from __future__ import annotations

import tomllib

import pytest

import identify_truth as IT
from rlgsim.lab.cli.main import main


@pytest.fixture(scope="module")
def unit(tmp_path_factory):
    """A 4.9 h rlg_single unit with trplg_001's law (gradients, UHFO) and noise."""
    folder = tmp_path_factory.mktemp("next")
    th = IT.thermal_truth(folder, {})
    dev = IT.device_truth(folder, th)
    return folder, IT.simulate(IT.scenario(folder, dev), folder / "r.h5"), dev


def test_suggested_programme_shrinks_the_promised_standard_errors(unit, capsys):
    from rlgsim.lab.identify import identify
    from rlgsim.lab.identify.next_experiment import recorded_se
    folder, rec, dev = unit
    a = identify(rec, folder / "a", suggest_programme=True)
    s = a.suggestion
    assert s is not None and s.targets and {"rate"} <= set(s.targets)
    text = a.next_path.read_text()
    sc = tomllib.loads(text)
    assert sc["device"] == "device.toml" and sc["chamber"]["segments"]
    assert "predicted" in text.split("name =")[0]               # the promise, in the header
    # the check: the programme simulated on the twin and identified again (by the CLI)
    assert main(["run", str(a.next_path), "-o", str(folder / "next.h5"), "-q"]) == 0
    assert main(["identify", str(folder / "next.h5"), "--suggest-programme",
                 "-o", str(folder / "b")]) == 0
    out = capsys.readouterr().out
    assert "next experiment" in out
    b = identify(folder / "next.h5", folder / "b2")
    dev_t = tomllib.loads(dev.read_text())
    got = recorded_se(b.data, b.thermal.nodes_c, b.thermal.network.node_names, dev_t, a.laws,
                      b.laws.noise, b.laws.bias.c_hat, list(s.se))
    for t in s.targets:
        now, pred = s.se[t]
        assert pred < now, (t, now, pred)                      # it promised to shrink it
        assert got[t] < now, (t, now, got[t])                  # and it did
        # as predicted: the design takes the setpoint for the air and this recording's noise
        assert 0.67 < got[t] / pred < 1.5, (t, pred, got[t])
