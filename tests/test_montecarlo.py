"""``rlgsim montecarlo`` end to end: the shipped demo study (on a short cycle) on 1 worker,
2 workers and a Dask LocalCluster gives the same bytes (a campaign killed with SIGKILL resumes
without recomputing finished units: tests/test_kill.py); a failing unit is recorded; the drawn thermal network of a unit is keyed by
(device_seed, unit); user mistakes are one line with exit code 2."""

from __future__ import annotations

import csv
import dataclasses
import io
import pathlib
import time

import h5py
import numpy as np
import pytest

from rlgsim.lab.cli.main import main
from scenario_helpers import TINY_SCENARIO, demo_on_tiny_cycle, one_line, tiny_study

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEMO = ROOT / "scenarios" / "studies" / "demo.toml"


def _units_table(folder: pathlib.Path) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO((folder / "units.csv").read_text())))


def test_demo_study_same_bytes_on_one_and_two_workers_and_a_dask_cluster(tmp_path, capsys):
    """The three campaigns go through the command's entry point (``main``) in this process:
    their units run in other processes all the same (the local pool's workers, the cluster's),
    which is what the comparison is about; a campaign as its own ``python -m rlgsim`` process is
    test_kill.py's (one, killed mid-campaign) — a process start here cost seconds of the suite
    (issue 30)."""
    distributed = pytest.importorskip("distributed")
    n = "2"
    demo = str(demo_on_tiny_cycle(tmp_path / "study"))

    def campaign(out: str, *how: str) -> None:
        code = main(["montecarlo", demo, "--units", n, *how, "-o", str(tmp_path / out),
                     "--quiet"])
        assert code == 0, capsys.readouterr().err

    campaign("w1", "--workers", "1")
    campaign("w2", "--workers", "2")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        campaign("dask", "--scheduler", cluster.scheduler_address)
    for d in ("w1", "w2", "dask"):       # a failed unit (e.g. a worker lost on a loaded
        failed = [u for u in _units_table(tmp_path / d) if u["status"] != "ok"]   # machine)
        assert not failed, f"{d}: {failed}"    # is not a byte difference: say which it was
    one, two, dask = ((tmp_path / d / "results.csv").read_bytes() for d in ("w1", "w2", "dask"))
    assert one == two == dask
    assert (tmp_path / "w1" / "units.csv").read_bytes() == \
        (tmp_path / "dask" / "units.csv").read_bytes()
    rows = list(csv.DictReader(io.StringIO(one.decode())))
    assert {r["unit"] for r in rows} == {"0", "1"}
    assert {"raw", "LSSVM T, dT/dt, U"} <= {r["compensator"] for r in rows}
    assert not any(r["metric"] == "fit_s" for r in rows), "timings would break determinism"
    # the drawn thermal network differs between units (unit 0: the nominal design)
    units = _units_table(tmp_path / "w1")
    assert [u["status"] for u in units] == ["ok"] * 2
    taus = [float(u["thermal.tau_max_s"]) for u in units]
    assert len(set(taus)) == 2
    report = (tmp_path / "w1" / "report.md").read_text()
    assert "Distribution per compensator" in report and "Worst units" in report
    assert (tmp_path / "w1" / "spread_stability_after.png").stat().st_size > 1000


def test_a_failing_unit_is_recorded_and_the_others_finish(tmp_path):
    from mc_toy_units import toy_unit
    from rlgsim.lab.cli.montecarlo import run

    path = run({"seed": 3, "fail_units": [2]}, 5, tmp_path, workers=2, quiet=True,
               unit_fn=toy_unit, title="toy")
    units = _units_table(tmp_path)
    assert [u["status"] for u in units] == ["ok", "ok", "failed", "ok", "ok"]
    assert "unit 2 broke on purpose" in units[2]["error"]
    rows = list(csv.DictReader(io.StringIO((tmp_path / "results.csv").read_text())))
    assert sorted({int(r["unit"]) for r in rows}) == [0, 1, 3, 4]
    text = path.read_text()
    assert "Failed units" in text and "broke on purpose" in text
    assert "4 ok, 1 failed" in text


def test_thermal_realisation_keyed_by_device_seed_and_unit(tmp_path):
    from rlgsim.sim.run.scenario import parse_scenario
    from rlgsim.sim.run.simulate import simulate
    from rlgsim.sim.stages.thermal import realised_network

    sc = parse_scenario(TINY_SCENARIO, "tiny_cycle.toml")
    nominal = sc.device.thermal.network

    def net(device_seed, unit):
        return realised_network(dataclasses.replace(sc, device_seed=device_seed, unit=unit))

    assert net(5, 0) is nominal                        # unit 0: the nominal design
    a, a2, b, c = net(5, 1), net(5, 1), net(5, 2), net(6, 1)
    for x in (b, c):
        assert not np.array_equal(a.capacitance_j_per_k, x.capacitance_j_per_k)
    for attr in ("capacitance_j_per_k", "conductance_w_per_k", "ambient_conductance_w_per_k",
                 "power_w"):
        assert np.array_equal(getattr(a, attr), getattr(a2, attr))
    # same noise seed, other device seed: another unit; the spread follows the tolerance
    tol = nominal.tolerance
    z = np.log(np.concatenate([net(7, u).capacitance_j_per_k / nominal.capacitance_j_per_k
                               for u in range(1, 41)]))
    assert np.std(z) == pytest.approx(tol.capacitance_rel, rel=0.15)
    # the dataset records the drawn factors
    run1 = dataclasses.replace(sc, device_seed=5, unit=1, duration_s=1800.0)
    path = simulate(run1, tmp_path / "u1.h5", progress=False)
    with h5py.File(path) as f:
        g = f["thermal"]
        np.testing.assert_array_equal(g["capacitance"][...], a.capacitance_j_per_k)
        np.testing.assert_allclose(g["capacitance_factor"][...],
                                   a.capacitance_j_per_k / nominal.capacitance_j_per_k)
        np.testing.assert_allclose(g["link_conductance_factor"][...] ** 0, 1.0)
        assert np.std(np.log(g["link_conductance_factor"][...])) > 0
        assert g["power_factor"].shape == (nominal.n_nodes,)


@pytest.mark.parametrize("args,message", [
    (["--units", "0"], "must be >= 1"),
    (["--units", "2", "--workers", "0"], "must be >= 1"),
    (["--units", "2", "--scheduler", "nonsense"], "scheduler"),
    (["--units", "2", "--workers", "2", "--scheduler", "tcp://x:1"], "not allowed with"),
])
def test_user_mistakes_are_one_line_exit_2(tmp_path, capsys, args, message):
    assert message in one_line(capsys, ["montecarlo", str(DEMO), *args,
                                        "-o", str(tmp_path / "o"), "--quiet"])


def test_unknown_study_and_unreachable_scheduler_exit_2(tmp_path, capsys):
    assert "no_such_study" in one_line(capsys, ["montecarlo", "no_such_study", "--units", "2",
                                                "--quiet"])
    t0 = time.monotonic()
    assert "cannot connect" in one_line(capsys, [
        "montecarlo", str(DEMO), "--units", "2", "--scheduler", "tcp://127.0.0.1:9",
        "-o", str(tmp_path / "o"), "--quiet"])
    assert time.monotonic() - t0 < 10


def test_chamber_variation_per_unit(tmp_path):
    from rlgsim.sim.thermal.chamber import Ramp
    from rlgsim.lab.cli.montecarlo import montecarlo_unit, study_payload
    from rlgsim.lab.study import load_study, scenario_for
    from rlgsim.sim.run.unit_variations import ChamberVariation, draw, varied

    study = load_study(str(tiny_study(tmp_path)))
    plain = scenario_for(study, "tiny_cycle.toml", unit=3)
    var = ChamberVariation(offset_c=0.5, rate_rel=0.1)
    with varied(var):
        a = scenario_for(study, "tiny_cycle.toml", unit=3)
        a2 = scenario_for(study, "tiny_cycle.toml", unit=3)
        b = scenario_for(study, "tiny_cycle.toml", unit=4)
    assert scenario_for(study, "tiny_cycle.toml", unit=3).chamber == plain.chamber  # only in varied()
    offset, factor = draw(plain.seed, 3, var)
    assert a.chamber == a2.chamber and a.chamber != b.chamber
    assert a.chamber.start_c == pytest.approx(plain.chamber.start_c + offset)
    ramps = [(p, q) for p, q in zip(plain.chamber.segments, a.chamber.segments)
             if isinstance(p, Ramp)]
    assert ramps and all(q.to_c == pytest.approx(p.to_c + offset) and
                         q.rate_c_per_min == pytest.approx(p.rate_c_per_min * factor)
                         for p, q in ramps)
    payload = study_payload(study)
    base = montecarlo_unit(payload, 1)
    varied_out = montecarlo_unit({**payload, "chamber_variation": {"offset_c": 0.5,
                                                                   "rate_rel": 0.1}}, 1)
    assert "chamber.offset_c" not in base["params"]
    assert varied_out["params"]["chamber.rate_factor"] == pytest.approx(
        draw(plain.seed, 1, var)[1])
    assert varied_out["rows"] != base["rows"]
    assert base["params"]["thermal.tau_max_s"] == varied_out["params"]["thermal.tau_max_s"]
