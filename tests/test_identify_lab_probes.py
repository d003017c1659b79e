"""A lab's own recording through identification (issue 28; src/rlgsim/lab/identify/
probe_mapping.py): probes named the lab's way (not the template's), three gyros with one
per-axis UHFO column (``uhfo_z_v``) and a timestamp column the sidecar ignores. The sidecar's
``[probes]`` table places one probe; identification proposes the others by fit, prints the
mapping, and the twin is written. The mapping by fit is checked against the truth (a simulated
unit whose probes were renamed): each recorded probe lands on its own template probe or on one
that reads the same in the template (mirror points of the symmetric block)."""

from __future__ import annotations

import pathlib
import tomllib

import numpy as np
import pandas as pd
import pytest

import identify_truth as IT
from rlgsim.ground.errors import UserInputError
from rlgsim.lab.cli.main import main

#: lab name -> the template probe it really is
LAB = {"block_top": "g.A", "anode": "g.D", "mount_side": "g.G", "case": "housing"}


@pytest.fixture(scope="module")
def lab_csv(tmp_path_factory):
    """A 4.9 h rlg_single unit (trplg_001 gyro z with UHFO) exported and reshaped as a lab
    would log it: four renamed probes, gyros x and y beside z, ``uhfo_z_v``, a timestamp."""
    folder = tmp_path_factory.mktemp("lab")
    th = IT.thermal_truth(folder, {})
    rec = IT.simulate(IT.scenario(folder, IT.device_truth(folder, th)), folder / "r.h5")
    from rlgsim.ground.recording_export import export
    out = export(str(rec), "csv", str(folder / "export.csv"))
    t = pd.read_csv(out.table)
    lab = pd.DataFrame({"time_s": t["time_s"],
                        "timestamp": pd.to_datetime(t["time_s"], unit="s",
                                                    origin="2026-11-26").astype(str)})
    rng = np.random.default_rng(5)
    for a in ("x", "y"):                # two more gyros: other noise around the same counts
        lab[f"gyro_{a}_pulses"] = t["gyro_z_pulses"] + rng.integers(-1, 2, len(t))
    lab["gyro_z_pulses"] = t["gyro_z_pulses"]
    for name, probe in LAB.items():
        lab[f"probe_{name}_c"] = t[f"probe_{probe}_c"]
    for c in ("chamber_air_c", "power_on", "uhfo_z_v"):
        lab[c] = t[c]
    path = folder / "lab.csv"
    lab.to_csv(path, index=False)
    side = tomllib.loads(out.sidecar.read_text())
    path.with_suffix(".toml").write_text(
        '[recording]\nsample_rate_hz = 1.0\ntemperature_rate_hz = 1.0\n'
        'ignore_columns = ["timestamp"]\n'
        f'[gyro]\naxes = ["x", "y", "z"]\nscale_factor_pulses_per_arcsec = '
        f'{side["gyro"]["scale_factor_pulses_per_arcsec"]}\n'
        '[probes]\nblock_top = "g.A"\n', encoding="utf-8")
    return path


def _template_reading(data):
    from rlgsim.sim import presets
    from rlgsim.lab.identify.thermal_fit import build, twin_response
    net, probes = build(presets.load_thermal_file("rlg_single").data)
    _, reading = twin_response(net, probes, data.air_c, data.power, data.step_s)
    return {n: reading[:, i] for i, n in enumerate(probes.names)}


def test_mapping_by_fit_finds_each_probe_or_its_mirror(lab_csv):
    from rlgsim.sim import presets
    from rlgsim.lab.identify.probe_mapping import map_probes
    from rlgsim.lab.identify.recording_data import read_recording
    data = read_recording(lab_csv, gyro="z")
    assert data.probe_names == tuple(LAB) and data.uhfo_v is not None
    template = presets.load_thermal_file("rlg_single").data
    mapped, lines = map_probes(template, data, {}, str(lab_csv))
    read = _template_reading(data)
    for lab_name, got in zip(LAB, mapped.probe_names):
        true = LAB[lab_name]
        # the same probe, or one the template reads alike (within 1 mK all along)
        assert got == true or np.max(np.abs(read[got] - read[true])) < 1e-3, (lab_name, got)
    assert len(lines) == 1 and "mapped by fit" in lines[0] and "case → housing" in lines[0]
    # the sidecar's table wins for the probes it names; the fit places the rest
    mapped2, lines2 = map_probes(template, data, {"block_top": "g.B"}, str(lab_csv))
    assert mapped2.probe_names[0] == "g.B"
    assert lines2[0].startswith("probes mapped by the sidecar's [probes]: block_top → g.B; "
                                "the others mapped by fit")


@pytest.mark.parametrize("table, words", [
    ({"nosuch": "g.A"}, "sidecar [probes] 'nosuch': not a probe of the recording"),
    ({"case": "g.Z"}, "case = 'g.Z': not a probe of the thermal template"),
    ({"case": "g.A", "anode": "g.A"}, "two recorded probes map to the template probe 'g.A'"),
])
def test_bad_probe_tables_are_one_line(lab_csv, table, words):
    from rlgsim.sim import presets
    from rlgsim.lab.identify.probe_mapping import map_probes
    from rlgsim.lab.identify.recording_data import read_recording
    data = read_recording(lab_csv, gyro="z")
    with pytest.raises(UserInputError) as e:
        map_probes(presets.load_thermal_file("rlg_single").data, data, table, str(lab_csv))
    assert words in str(e.value) and "\n" not in str(e.value)


def test_lab_csv_goes_through_info_open_tree_and_identify(lab_csv, tmp_path, capsys):
    from rlgsim.ground.datatree import open_tree
    assert main(["info", str(lab_csv)]) == 0
    with open_tree(str(lab_csv)) as tree:
        assert list(tree["imu"]["gyro"].values) == ["x", "y", "z"]
        assert sorted(map(str, tree["probes"]["probe"].values)) == sorted(LAB)
    capsys.readouterr()
    code = main(["identify", str(lab_csv), "--device-template", "trplg_001",
                 "--thermal-template", "rlg_single", "--gyro", "z", "-o", str(tmp_path / "twin")])
    out = capsys.readouterr().out
    assert code == 0, out
    line = next(x for x in out.splitlines() if x.startswith("probes mapped"))
    assert line.startswith("probes mapped by the sidecar's [probes]: block_top → g.A; the "
                           "others mapped by fit") and "case → housing" in line
    dev = (tmp_path / "twin" / "device.toml").read_text()
    assert "others mapped by fit" in dev and tomllib.loads(dev)["gyro"]["bias"]
    th = tomllib.loads((tmp_path / "twin" / "thermal.toml").read_text())
    assert "probes" in th
    assert "Probes mapped by the sidecar" in (tmp_path / "twin" / "report.md").read_text()
