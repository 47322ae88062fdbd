"""The learner's process: torch's threads per training phase, and a ``malloc`` that keeps the
memory torch frees.

:func:`prepare_learner` sets both up; ``nbv-gym train`` (:func:`~nbv_gym.rl.train.train`) and
the RL perf suite call it before they build the model. Nothing here touches the environment
workers, whose map stores manage their pages themselves (:mod:`nbv_gym.mapping.store`).
"""

from __future__ import annotations

import ctypes
import os
import platform

#: ``mallopt`` parameters of glibc's ``malloc.h``.
M_TRIM_THRESHOLD = -1
M_MMAP_MAX = -4
#: Free memory at the top of the heap that glibc may hand back (the most ``mallopt`` takes).
TRIM_THRESHOLD = 2**31 - 1


def prepare_learner(threads: int, n_envs: int) -> tuple[int, int]:
    """Set this process up to learn next to ``n_envs`` environment workers: keep freed memory
    (:func:`keep_freed_memory`) and give torch the rollouts' threads of :func:`torch_threads`
    now. Returns both thread counts (the :class:`~nbv_gym.rl.callbacks.TorchThreads` callback
    switches between them)."""
    import torch

    keep_freed_memory()
    counts = torch_threads(threads, n_envs)
    torch.set_num_threads(counts[0])
    return counts


def torch_threads(threads: int, n_envs: int) -> tuple[int, int]:
    """Torch intra-op threads (during rollouts, during updates): ``threads`` for both when set.
    0: during rollouts one per core that no environment worker runs on (at least one) — more
    threads than free cores make OpenMP wait for descheduled threads: on a busy 2-core machine 2
    threads made the policy's forward passes 10 times slower than 1 (``nbv-gym bench --suite
    rl``) — and during updates, while the workers wait, one per core."""
    affinity = getattr(os, "sched_getaffinity", None)  # Linux only
    cores = len(affinity(0)) if affinity else os.cpu_count() or 1
    if threads:
        return threads, threads
    return max(1, cores - (n_envs if n_envs > 1 else 0)), cores


def keep_freed_memory() -> bool:
    """Make glibc's ``malloc`` keep the memory this process frees for its next allocations
    instead of handing it back to the system; returns False (and changes nothing) under another
    C library.

    torch takes its CPU tensors from ``malloc``, which maps every block above its threshold
    (128 KiB to 32 MiB) afresh and unmaps it when it is freed, so most operations of a PPO update
    on 256 observations write to new pages, each first write a page fault: ~230 k faults per
    update (``nbv-gym bench --suite rl``), 2 µs each on a virtual machine. Without mapped blocks
    and with the heap never trimmed, the update reuses its pages: 1.7 → 1.35 s per update.
    The price: the process keeps the heap of its peak use (the learner's peak is its update).
    """
    if platform.libc_ver()[0] != "glibc":
        return False
    libc = ctypes.CDLL(None)
    return bool(libc.mallopt(M_MMAP_MAX, 0)) and bool(
        libc.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD)
    )
