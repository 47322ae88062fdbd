"""Sweeps: many episodes (worlds × noise × policies × repeats), resumable, on a local process pool
or a Dask cluster, and the report that reproduces the NBV paper's figures and tables.

- :mod:`nbv_gym.sweep.config`: :class:`SweepConfig`, :func:`load_sweep_config`, run keys and seeds.
- :mod:`nbv_gym.sweep.runner`: :func:`run_sweep` (resume, retries, progress).
- :mod:`nbv_gym.sweep.backends`: the process-pool and Dask backends.
- :mod:`nbv_gym.sweep.worker`: one run in a worker process.
- :mod:`nbv_gym.sweep.folder`: the results folder layout and its consolidated tables.
- :mod:`nbv_gym.sweep.report`, :mod:`nbv_gym.reporting.inference`: figures, tables and their statistics.

Importing this package is light: pandas, matplotlib and dask load only when used.
"""

from nbv_gym.sweep.config import RunSpec, SweepConfig, load_sweep_config

__all__ = ["RunSpec", "SweepConfig", "build_report", "load_sweep_config", "run_sweep"]


def run_sweep(*args, **kwargs):
    """See :func:`nbv_gym.sweep.runner.run_sweep`."""
    from nbv_gym.sweep.runner import run_sweep as run

    return run(*args, **kwargs)


def build_report(*args, **kwargs):
    """See :func:`nbv_gym.sweep.report.build_report`."""
    from nbv_gym.sweep.report import build_report as build

    return build(*args, **kwargs)
