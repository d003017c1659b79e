"""The Monte Carlo engine: determinism across executors, resumption, failing units."""

from __future__ import annotations

import pathlib

import pytest

from rlgsim.lab.montecarlo import (finished_units, results_csv, run_campaign, params_csv,
                            load_records)
from rlgsim.lab.montecarlo_summary import summarise, worst_units
from rlgsim.ground.errors import UserInputError

from mc_toy_units import toy_unit

PAYLOAD = {"seed": 7}


def _table(tmp_path: pathlib.Path, name: str, **kw) -> str:
    records = run_campaign(toy_unit, PAYLOAD, 12, tmp_path / name, progress=False, **kw)
    return results_csv(records)


def test_same_bytes_on_one_and_two_workers_and_a_dask_cluster(tmp_path):
    one = _table(tmp_path, "w1", workers=1)
    two = _table(tmp_path, "w2", workers=2)
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        dask = _table(tmp_path, "dask", executor=client.get_executor())
    assert one == two == dask
    assert one.count("\n") == 1 + 12 * 2


def test_failing_unit_is_recorded_and_others_finish(tmp_path):
    payload = {**PAYLOAD, "fail_units": [3]}
    records = run_campaign(toy_unit, payload, 6, tmp_path, progress=False, workers=2)
    assert [r.unit for r in records] == list(range(6))
    failed = [r for r in records if r.status == "failed"]
    assert [r.unit for r in failed] == [3]
    assert "broke on purpose" in failed[0].error
    assert "broke on purpose" in params_csv(records)


def test_killed_worker_then_resume_gives_the_uninterrupted_table(tmp_path):
    reference = _table(tmp_path, "ref", workers=2)
    payload = {**PAYLOAD, "kill_units": [5], "kill_marker": str(tmp_path / "killed")}
    out = tmp_path / "killed_run"
    # max_pool_restarts=0: the campaign stops with units missing, like an interrupted run.
    run_campaign(toy_unit, payload, 12, out, progress=False, workers=2, max_pool_restarts=0)
    missing_after_kill = set(range(12)) - finished_units(out)
    assert 5 in missing_after_kill
    before = {u: (out / "units" / f"unit_{u:06d}.json").stat().st_mtime_ns
              for u in finished_units(out)}
    records = run_campaign(toy_unit, payload, 12, out, progress=False, workers=2)
    after = {u: (out / "units" / f"unit_{u:06d}.json").stat().st_mtime_ns for u in before}
    assert before == after, "finished units were recomputed"
    assert results_csv(records) == reference


def test_a_folder_of_another_campaign_is_refused(tmp_path):
    run_campaign(toy_unit, PAYLOAD, 2, tmp_path, progress=False, identity={"seed": 7})
    with pytest.raises(UserInputError, match="different campaign"):
        run_campaign(toy_unit, PAYLOAD, 2, tmp_path, progress=False, identity={"seed": 8})


def test_summary_statistics_and_worst_units(tmp_path):
    records = run_campaign(toy_unit, PAYLOAD, 40, tmp_path, progress=False, workers=2)
    rows = {(s.compensator, s.metric): s for s in summarise(records, baseline="raw")}
    fit = rows[("fit", "bias_stability")]
    raw_values = sorted(v for r in records for c, m, v in r.rows if c == "raw")
    assert rows[("raw", "bias_stability")].median == pytest.approx(
        (raw_values[19] + raw_values[20]) / 2)
    beats = sum(dict(((c, m), v) for c, m, v in r.rows)[("fit", "bias_stability")]
                < dict(((c, m), v) for c, m, v in r.rows)[("raw", "bias_stability")]
                for r in records) / 40
    assert fit.beats_baseline == pytest.approx(beats)
    worst = worst_units(records, "fit", "bias_stability", count=3)
    assert len(worst) == 3 and worst[0][1] >= worst[1][1] >= worst[2][1]
    assert "drift" in worst[0][2]
    assert load_records(tmp_path, 40)[0].unit == 0
