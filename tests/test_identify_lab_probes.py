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
        _SIDECAR.format(sf=side["gyro"]["scale_factor_pulses_per_arcsec"],
                        lat=side["site"]["latitude_deg"]) + _IDENTIFY, encoding="utf-8")
    return path


#: the lab's sidecar: what the table cannot say, and what identification needs (no flag)
_SIDECAR = ('[recording]\nsample_rate_hz = 1.0\ntemperature_rate_hz = 1.0\n'
            'ignore_columns = ["timestamp"]\n[site]\nlatitude_deg = {lat}\n'
            '[gyro]\naxes = ["x", "y", "z"]\nscale_factor_pulses_per_arcsec = {sf}\n'
            '[probes]\nblock_top = "g.A"\n')
_IDENTIFY = ('[identify]\ndevice_template = "trplg_001"\nthermal_template = "rlg_single"\n'
             'gyro = "z"\n')


def _variant(lab_csv, folder: pathlib.Path, sidecar: str) -> pathlib.Path:
    """The lab's table beside another sidecar."""
    path = folder / "lab.csv"
    path.write_bytes(lab_csv.read_bytes())
    path.with_suffix(".toml").write_text(sidecar, encoding="utf-8")
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
    # the sidecar alone: its [identify] table names the templates and the gyro
    code = main(["identify", str(lab_csv), "-o", str(tmp_path / "twin")])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "gyro `z`" in (tmp_path / "twin" / "report.md").read_text()
    assert "site:" not in out                        # the sidecar gives the latitude
    line = next(x for x in out.splitlines() if x.startswith("probes mapped"))
    assert line.startswith("probes mapped by the sidecar's [probes]: block_top → g.A; the "
                           "others mapped by fit") and "case → housing" in line
    dev = (tmp_path / "twin" / "device.toml").read_text()
    assert "others mapped by fit" in dev and tomllib.loads(dev)["gyro"]["bias"]
    th = tomllib.loads((tmp_path / "twin" / "thermal.toml").read_text())
    assert "probes" in th
    assert "Probes mapped by the sidecar" in (tmp_path / "twin" / "report.md").read_text()


def _sidecar_text(lab_csv, identify: str, site: bool = True) -> str:
    text = lab_csv.with_suffix(".toml").read_text().split("[identify]")[0]
    if not site:
        text = "\n".join(x for x in text.splitlines()
                          if x != "[site]" and not x.startswith("latitude_deg")) + "\n"
    return text + identify


@pytest.mark.parametrize("identify, words", [
    ("", "a recording needs a device template"),
    ('[identify]\ndevice_template = "trplg_001"\ngyro = "q"\n',
     "identify.gyro: value 'q' not allowed; must be one of the [gyro] axes (x, y, z)"),
    ('[identify]\ndevice = "trplg_001"\n', "identify.device: unknown key; allowed: "
                                          "device_template, gyro, thermal_template"),
])
def test_what_the_sidecar_lacks_is_one_line_before_any_fit(lab_csv, tmp_path, capsys, identify,
                                                           words):
    path = _variant(lab_csv, tmp_path, _sidecar_text(lab_csv, identify))
    assert main(["identify", str(path), "-o", str(tmp_path / "twin")]) == 2
    err = capsys.readouterr().err.strip()
    assert words in err and "\n" not in err and "Traceback" not in err
    assert not (tmp_path / "twin" / "device.toml").exists()
    if identify == "":                    # both ways of giving it are named
        assert "--device-template PRESET" in err and '[identify] device_template' in err


def test_sidecar_choices_flags_win_paths_beside_the_sidecar_and_the_site_note(lab_csv,
                                                                               tmp_path):
    from rlgsim.lab.identify.sidecar_choices import sidecar_choices
    (tmp_path / "presets").mkdir()
    (tmp_path / "presets" / "gyro12.toml").write_text("", encoding="utf-8")
    ident = '[identify]\ndevice_template = "presets/gyro12.toml"\ngyro = "y"\n'
    path = _variant(lab_csv, tmp_path, _sidecar_text(lab_csv, ident, site=False))
    c = sidecar_choices(str(path), None, None, None)
    assert c.device_template == str(tmp_path / "presets" / "gyro12.toml")
    assert c.thermal_template is None and c.gyro == "y"
    assert len(c.notes) == 1 and c.notes[0].startswith(
        "site: [site] latitude_deg not in the sidecar lab.toml; the Earth rate on the gyro axis "
        "is taken at latitude 34°")
    c = sidecar_choices(str(path), "trplg_001", "rlg_single", "z")   # the flags win
    assert (c.device_template, c.thermal_template, c.gyro) == ("trplg_001", "rlg_single", "z")
    assert sidecar_choices(str(lab_csv), None, None, None).notes == ()


def test_the_fits_run_with_one_blas_thread(lab_csv, tmp_path, monkeypatch):
    """identify limits BLAS to one thread around its fits (src/rlgsim/lab/identify/twin.py),
    whatever the caller's pool: seen from inside the thermal fit with the caller at two."""
    from threadpoolctl import threadpool_info, threadpool_limits
    import rlgsim.lab.identify.twin as twin

    def blas_threads() -> list[int]:
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    class Stop(Exception):
        pass

    seen: list[int] = []

    def spy(*args, **kwargs):
        seen.extend(blas_threads())
        raise Stop

    monkeypatch.setattr(twin, "fit_thermal", spy)
    with threadpool_limits(limits=2, user_api="blas"):
        if not blas_threads() or max(blas_threads()) < 2:
            pytest.skip("no BLAS here that runs two threads")
        with pytest.raises(Stop):
            twin.identify(str(lab_csv), tmp_path / "twin")
        assert max(blas_threads()) == 2                  # the caller's pool is given back
    assert seen and max(seen) == 1
