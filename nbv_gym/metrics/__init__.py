"""Map-quality metrics: cuboid coverage / L1 / Q, WD_occ, Empir3D and the indicator tests.

Everything takes plain arrays (no mapping code): a probability grid and a ground-truth grid for the
cuboid metrics and WD_occ, two (n, 3) point clouds for Empir3D.
"""

from __future__ import annotations

import importlib

from nbv_gym.core.errors import NbvGymError


class MetricInputError(NbvGymError, ValueError):
    """Arrays or files given to a metric do not fit (shape, resolution, emptiness, format)."""


#: public name → submodule; imported on first use so that ``import nbv_gym.cli.evaluate`` (and
#: ``nbv-gym --help``) does not load numba, scipy or POT.
_EXPORTS = {
    "COV_SETTINGS": "cuboids",
    "CuboidConfig": "cuboids",
    "CuboidMetrics": "cuboids",
    "QualityConfig": "cuboids",
    "QualitySummary": "cuboids",
    "QualityTracker": "tracker",
    "benchmark_grid": "cuboids",
    "evaluate_cuboids": "tracker",
    "q_paper": "cuboids",
    "Empir3DConfig": "empir3d_config",
    "Empir3DResult": "empir3d",
    "chamfer_hausdorff": "empir3d",
    "empir3d": "empir3d",
    "IndicatorTest": "indicators",
    "indicator_test": "indicators",
    "indicator_tests": "indicators",
    "pot_wd_occ": "wasserstein",
    "wd_occ": "wasserstein",
    "wd_occ_cuboids": "wasserstein",
}

__all__ = ["MetricInputError", *_EXPORTS]


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module 'nbv_gym.metrics' has no attribute {name!r}")
    return getattr(importlib.import_module(f"nbv_gym.metrics.{_EXPORTS[name]}"), name)
