"""Scoring a map or a point cloud that lies in files: the probability grid of a saved map or a
``.npy`` array, the ground truth of a world or a ``.npy`` array, the per-cuboid metrics' summary and
CSV (``nbv-gym evaluate``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nbv_gym.core.errors import missing_file
from nbv_gym.mapping.mapfile import load_map, recorded_world
from nbv_gym.metrics import MetricInputError
from nbv_gym.metrics.empir3d_config import Empir3DConfig

CSV_NAME = "cuboids.csv"


SUMMARY_NAME = "summary.json"


REGIONS_NAME = "regions.csv"


def check_map_world(map_path: Path, world: str | None) -> None:
    """Refuse to score a saved map against a world other than the one it records."""
    if world is None or map_path.suffix != ".npz" or not map_path.is_file():
        return
    from nbv_gym.worlds import load_spec

    recorded = recorded_world(map_path)
    spec = load_spec(world)
    if recorded and recorded != f"{spec.name}@{spec.digest()}":
        name = recorded.partition("@")[0]
        raise MetricInputError(
            f"{map_path} is a map of world {recorded!r} (name@spec digest), not of {world!r} "
            f"({spec.name}@{spec.digest()}); score it with --world {name} (or that world's spec)"
        )


def load_probability(path: Path, grid) -> np.ndarray:
    """The (X, Y, Z) float32 probability grid of a saved map (.npz) or a plain array (.npy)."""
    if not path.is_file():
        raise MetricInputError(f"{path}: the map file {missing_file(path)}")
    if path.suffix not in (".npz", ".npy"):
        raise MetricInputError(
            f"{path}: --map takes a saved map (.npz, as `nbv-gym run` writes) or a probability "
            f"grid (.npy), not a {path.suffix or 'suffix-less'} file; score point clouds with "
            "`nbv-gym evaluate REFERENCE CANDIDATE`"
        )
    if path.suffix == ".npy":
        prob = _load_npy(path)
        if prob.shape != grid.shape or not np.issubdtype(prob.dtype, np.floating):
            raise MetricInputError(
                f"{path}: expected a float probability grid of shape {grid.shape} (the 0.1 m "
                f"benchmark grid), got {prob.dtype} {prob.shape}"
            )
        bad = ~((prob >= 0) & (prob <= 1))  # NaN too
        if bad.any():
            raise MetricInputError(
                f"{path}: probabilities must lie in [0, 1]; {int(bad.sum())} value(s) do not "
                f"(e.g. {float(prob[bad].flat[0])})"
            )
        return prob.astype(np.float32, copy=False)

    return load_map(path).probability(grid)


def load_ground_truth(world: str | None, path: Path | None, grid) -> np.ndarray:
    """The (X, Y, Z) bool ground truth of ``world`` or of the ``.npy`` file ``path`` on ``grid``."""
    if (world is None) == (path is None):
        raise MetricInputError("give exactly one of --world NAME and --ground-truth GT.npy")
    if world is not None:
        from nbv_gym.worlds import load_world

        return load_world(world).ground_truth.occupancy(grid)
    if path is None or not path.is_file():
        raise MetricInputError(f"{path}: the ground-truth file {missing_file(path)}")
    truth = _load_npy(path)
    if truth.shape != grid.shape or truth.dtype != bool:
        raise MetricInputError(
            f"{path}: expected a bool ground-truth grid of shape {grid.shape}, got {truth.dtype} {truth.shape}"
        )
    return truth


def _load_npy(path: Path) -> np.ndarray:
    from nbv_gym.core.arrayfiles import read_npy
    from nbv_gym.core.errors import DataFileError

    try:
        return read_npy(path)
    except DataFileError as error:
        raise MetricInputError(str(error)) from None
    except OSError as error:
        raise MetricInputError(f"{path}: unreadable .npy file ({error})") from None


def map_summary(metrics, wd: np.ndarray) -> dict:
    """The map's quality (Q, Q_paper, coverage, L1, counts) and the Wasserstein distance statistics
    of its occupied cuboids (``wd``: per cuboid), as one flat dict."""
    summary = metrics.summary()
    settings = metrics.config.cov_settings
    occ = wd[metrics.u_occ]
    observed = wd[metrics.u_occ & metrics.observed]
    result = {"q": summary.q, "q_paper": summary.q_paper}
    result.update(
        {f"cov_p{p:g}_d{d:g}": c for (p, d), c in zip(settings, summary.cov, strict=True)}
    )
    result.update({"l1": summary.l1, "n_occ": summary.n_occ, "n_empty": summary.n_empty})
    result["n_observed"] = summary.n_observed
    for name, values in (("wd_occ", occ), ("wd_occ_observed", observed)):
        stats = _statistics(values)
        result.update({f"{name}_{k}": v for k, v in stats.items()})
    return result


def _statistics(values: np.ndarray) -> dict[str, float]:
    if values.size == 0:
        return {
            "mean": float("nan"),
            "median": float("nan"),
            "min": float("nan"),
            "max": float("nan"),
        }
    return {
        "mean": float(values.mean()),
        "median": float(np.median(values)),
        "min": float(values.min()),
        "max": float(values.max()),
    }


def write_cuboid_csv(path: Path, metrics, wd: np.ndarray, grid) -> None:
    """Write one CSV row per cuboid of ``grid``: its index, low corner in metres, occupancy,
    observation, coverage, L1, Wasserstein distance and quality."""
    n = metrics.config.cuboid_voxels
    index = np.argwhere(np.ones(metrics.u_occ.shape, bool))
    low = grid.low + index * n * grid.res
    columns = {"ci": index[:, 0], "cj": index[:, 1], "ck": index[:, 2]}
    columns.update({f"{a}_low_m": np.round(low[:, i], 6) for i, a in enumerate("xyz")})
    columns.update(
        {
            "u_occ": metrics.u_occ.ravel().astype(int),
            "observed": metrics.observed.ravel().astype(int),
        }
    )
    for (p, d), cov in zip(metrics.config.cov_settings, metrics.cov, strict=True):
        columns[f"cov_p{p:g}_d{d:g}"] = cov.ravel()
    columns.update(
        {"l1": metrics.l1.ravel(), "wd_occ": wd.ravel(), "quality": metrics.quality.ravel()}
    )
    write_rows(
        path, [dict(zip(columns, row, strict=True)) for row in zip(*columns.values(), strict=True)]
    )


def write_rows(path: Path, rows: list[dict]) -> None:
    """Write ``rows`` (dicts with the same keys) to a CSV file at ``path``."""
    import csv

    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]) if rows else [])
        writer.writeheader()
        writer.writerows(rows)


def empir3d_config(epsilon: float | None, region: float | None) -> Empir3DConfig:
    """The Empir3D config of the options given; the config's own value for each option left out."""
    given = {"epsilon_m": epsilon, "region_m": region}
    return Empir3DConfig(**{k: v for k, v in given.items() if v is not None})
