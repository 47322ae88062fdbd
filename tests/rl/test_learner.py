"""The learner's process: torch's threads per training phase, and malloc keeping freed memory."""

from __future__ import annotations

import os
import platform
import resource

import numpy as np
import pytest

th = pytest.importorskip("torch")
pytest.importorskip("sb3_contrib")

from nbv_gym.rl.callbacks import TorchThreads  # noqa: E402
from nbv_gym.rl.learner import keep_freed_memory, prepare_learner, torch_threads  # noqa: E402


def test_torch_threads_explicit_or_one_per_free_core_and_all_cores_for_updates():
    cores = len(os.sched_getaffinity(0))
    assert torch_threads(3, n_envs=2) == (3, 3)
    assert torch_threads(0, n_envs=1) == (cores, cores)
    assert torch_threads(0, n_envs=10_000) == (1, cores)  # more environments than cores
    before = th.get_num_threads()
    try:
        assert prepare_learner(0, n_envs=10_000) == (1, cores) and th.get_num_threads() == 1
        switch = TorchThreads(1, 5)
        switch._on_rollout_end()
        assert th.get_num_threads() == 5  # the PPO update: the workers wait
        switch._on_rollout_start()
        assert th.get_num_threads() == 1
    finally:
        th.set_num_threads(before)


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="mallopt is glibc's")
def test_freed_memory_is_reused_without_page_faults():
    """After keep_freed_memory, a 64 MiB block freed and allocated again is written without a
    page fault (malloc would otherwise map it afresh: ≥ 32 faults even with 2 MiB pages)."""

    def faults_writing(size: int) -> int:
        before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        np.ones(size, np.uint8)
        return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before

    assert keep_freed_memory()
    faults_writing(64 << 20)
    assert faults_writing(64 << 20) <= 8
