"""Training with the environments on a Dask LocalCluster (2 worker processes): the same model,
bit for bit, as with the local lean workers from the same seed; a worker killed mid-rollout
costs its environments' episodes (``worker lost`` in ``episodes.csv``), not the run; a cluster
that loses every worker stops with an error naming the checkpoint it saved."""

from __future__ import annotations

import csv
import os
import zipfile
from dataclasses import replace

import pytest

th = pytest.importorskip("torch")
pytest.importorskip("sb3_contrib")
pytest.importorskip("distributed")

from stable_baselines3.common.callbacks import BaseCallback  # noqa: E402

from nbv_gym.core.errors import ClusterError, ConfigError  # noqa: E402
from nbv_gym.env.task import TaskConfig  # noqa: E402
from nbv_gym.rl import daskvec  # noqa: E402
from nbv_gym.rl.config import LearningConfig, TrainConfig  # noqa: E402
from nbv_gym.rl.train import train  # noqa: E402

STEPS = 64


@pytest.fixture(scope="module")
def config(world) -> TrainConfig:
    return TrainConfig(
        total_timesteps=STEPS,
        n_envs=2,
        train_worlds=(world,),
        eval_worlds=(),
        task=TaskConfig(name="budget", budget_scans=4),
        learning=LearningConfig(n_steps=16, batch_size=16, n_epochs=2),
        checkpoint_every_steps=0,
        eval_every_steps=0,
        torch_threads=1,
        seed=3,
    )


def policy_tensors(run) -> dict:
    """The tensors of ``policy.pth`` in the run's final model."""
    with zipfile.ZipFile(run / "final_model.zip") as archive, archive.open("policy.pth") as f:
        return th.load(f, map_location="cpu")


def episodes(run) -> list[dict]:
    with open(run / "episodes.csv", newline="") as file:
        return list(csv.DictReader(file))


class KillWorker(BaseCallback):
    """At the ``at``-th step, kill the worker process holding environment 0 (``os._exit``),
    or with ``everyone`` shut the whole LocalCluster down."""

    def __init__(self, at: int, everyone: bool = False):
        super().__init__()
        self.at, self.everyone, self.killed = at, everyone, ""

    def _on_step(self) -> bool:
        if self.n_calls == self.at:
            envs = self.training_env
            if self.everyone:
                envs.cluster.scale(0)
            else:
                self.killed = envs.worker_of(0)
                try:
                    envs.client.run(os._exit, 1, workers=[self.killed])
                except Exception:  # the worker died before it could answer
                    pass
        return True


@pytest.mark.slow  # two trainings, a LocalCluster started: about a minute on 2 busy cores
def test_a_local_cluster_trains_the_model_of_the_local_workers_bit_for_bit(config, tmp_path):
    local = train(config, tmp_path / "local", progress_bar=False)
    cluster = train(replace(config, scheduler="local"), tmp_path / "cluster", progress_bar=False)
    assert local.num_timesteps == cluster.num_timesteps == STEPS
    ours, theirs = policy_tensors(tmp_path / "cluster"), policy_tensors(tmp_path / "local")
    assert sorted(ours) == sorted(theirs)
    assert all(th.equal(ours[k], theirs[k]) for k in theirs)
    assert episodes(tmp_path / "cluster") == episodes(tmp_path / "local")
    assert {row["end"] for row in episodes(tmp_path / "local")} == {"reached max_steps = 4"}


@pytest.mark.slow  # a LocalCluster, a worker killed and its environments rebuilt: ~1 min
def test_a_worker_killed_mid_rollout_truncates_its_episodes_and_training_goes_on(
    config, tmp_path, caplog
):
    kill = KillWorker(at=6)
    model = train(replace(config, scheduler="local"), tmp_path, progress_bar=False,
                  callbacks=(kill,))  # fmt: skip
    assert kill.killed and model.num_timesteps == STEPS
    assert f"Dask worker {kill.killed} was lost: environment(s) [0] rebuilt" in caplog.text
    rows = episodes(tmp_path)
    lost = [row for row in rows if row["end"] == daskvec.LOST]
    assert len(lost) == 1  # environment 0's episode; environment 1 shared no worker with it
    assert 0 <= int(lost[0]["length"]) < 4 and 0 < float(lost[0]["q"]) <= 1
    assert len(rows) > len(lost) and (tmp_path / "final_model.zip").exists()


def test_a_cluster_without_workers_stops_with_the_error_and_a_saved_checkpoint(
    config, tmp_path, monkeypatch
):
    monkeypatch.setattr(daskvec, "WORKER_WAIT_S", 1.0)
    with pytest.raises(ClusterError, match=r"No Dask worker is left .* saved as .*model_\d+_steps"):
        train(replace(config, scheduler="local"), tmp_path, progress_bar=False,
              callbacks=(KillWorker(at=6, everyone=True),))  # fmt: skip
    assert len(list((tmp_path / "checkpoints").glob("model_*_steps.zip"))) == 1


class ClosingWorker:
    """A call's future and a client as a worker closing under the call shows them: the call
    fails with the worker's executor shut down, and the scheduler lists the worker as ``status``
    (None: not at all)."""

    def __init__(self, status: str | None):
        self.status = status

    def result(self, timeout):
        raise RuntimeError("cannot schedule new futures after shutdown")

    def scheduler_info(self, n_workers: int, **bounded) -> dict:  # callback_timeout
        return {"workers": {"tcp://w": {"status": self.status}} if self.status else {}}


@pytest.mark.parametrize("status, lost", [(None, True), ("closing_gracefully", True),
                                          ("running", False)])  # fmt: skip
def test_a_call_that_fails_as_its_worker_closes_counts_as_the_worker_lost(status, lost):
    """A cluster scaled down closes a worker under a call; that is a lost worker (its
    environments rebuilt, or the no-worker error), while a failure on a worker that stays
    running is an error of its own."""
    envs = object.__new__(daskvec.DaskVecEnv)
    envs.client = closing = ClosingWorker(status)
    with pytest.raises(daskvec._WorkerLost if lost else RuntimeError):
        envs._result(closing, "tcp://w")


def test_a_scheduler_that_is_not_an_address_is_refused():
    with pytest.raises(ConfigError, match=r"scheduler: expected .*tcp://host:8786, got 'tpc'"):
        TrainConfig(scheduler="tpc")


def test_a_tls_scheduler_needs_the_sweeps_tls_settings(config):
    """Training reads the same TLS settings as sweeps (nbv_gym.core.cluster)."""
    import dask.config

    from nbv_gym.core.cluster import TLS_SETTINGS
    from nbv_gym.rl.train import make_vec_env

    with dask.config.set({key: None for key in TLS_SETTINGS}):
        with pytest.raises(ClusterError, match=r"tls\.ca-file is not set.*DASK_DISTRIBUTED__"):
            make_vec_env(replace(config, scheduler="tls://127.0.0.1:1"))
