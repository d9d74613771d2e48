"""``--dask``: a campaign on a Dask cluster gives the local runner's results; clear errors without it."""
from __future__ import annotations

import sys

import pytest

from mavreg.cli.main import main
from mavreg.experiments import on_dask
from mavreg.experiments.definitions import REGULATOR, SE3, lag
from mavreg.experiments.runner import run_experiment


def _small():
    return lag(0, leads_m=(2.0,), controllers=(REGULATOR, SE3), saturations_n=(None,), max_time_s=1.0)


def test_a_dask_cluster_gives_the_local_results_float_for_float():
    distributed = pytest.importorskip("distributed", reason="dask.distributed is not installed "
                                      "(pip install 'mavreg[dask]'); --dask cannot be tested")
    local = run_experiment(_small(), "sim", 1, progress=None)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        remote = run_experiment(_small(), "sim", 1, progress=None, dask_address=cluster.scheduler_address)
    assert [o.metrics for o in remote] == [o.metrics for o in local]
    assert all(o.metrics is not None for o in remote) and remote[1].metrics["overspeed_m_s"] > 0.5


def test_without_dask_installed_dask_is_one_line_and_exit_2(monkeypatch, capsys, tmp_path):
    monkeypatch.setitem(sys.modules, "distributed", None)            # import distributed -> ImportError
    code = main(["experiment", "lag", "--dask", "tcp://127.0.0.1:8786", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.strip().count("\n") == 0
    assert "--dask needs dask.distributed" in err and "pip install" in err
    assert not (tmp_path / "out").exists()


class _Client:
    """What on_dask asks of a client: ``run`` on every worker."""

    def __init__(self, answers):
        self.answers = answers

    def run(self, fn, *args):
        return self.answers(fn(*args))


def test_a_worker_with_other_code_or_files_is_refused_before_any_run(tmp_path):
    exp = _small()
    with pytest.raises(ValueError, match="runs another mavreg"):
        on_dask._check_workers(_Client(lambda mine: {"tcp://w1": {**mine, "code": "0" * 64}}), exp, None)
    with pytest.raises(ValueError, match="cannot read .*barrel_roll.yaml"):
        on_dask._check_workers(_Client(lambda mine: {"tcp://w1": {
            **mine, "files": {f: (None if f.endswith("barrel_roll.yaml") else h) for f, h in mine["files"].items()}}}),
            exp, None)
    with pytest.raises(ValueError, match="cannot write"):
        on_dask._check_workers(_Client(lambda mine: {"tcp://w1": {**mine, "out_dir": False}}), exp, tmp_path)
    on_dask._check_workers(_Client(lambda mine: {"tcp://w1": mine, "tcp://w2": mine}), exp, tmp_path)
    with pytest.raises(ValueError, match="no workers"):
        on_dask._check_workers(_Client(lambda mine: {}), exp, None)
