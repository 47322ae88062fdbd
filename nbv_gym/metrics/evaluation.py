"""Scoring a map or a point cloud that lies in files: the probability grid of a saved map or a
``.npy`` array, the ground truth of a world or a ``.npy`` array, the per-cuboid metrics' summary and
CSV (``nbv-gym evaluate``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nbv_gym.core.errors import MissingExtraError, missing_file
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


def check_probability_file(path: Path) -> None:
    """:class:`MetricInputError` unless ``path`` is a file a probability grid is read from (a
    saved map .npz or a plain .npy array): checked before any world is built."""
    if not path.is_file():
        raise MetricInputError(f"{path}: the map file {missing_file(path)}")
    if path.suffix not in (".npz", ".npy"):
        raise MetricInputError(
            f"{path}: --map takes a saved map (.npz, as `nbv-gym run` writes) or a probability "
            f"grid (.npy), not a {path.suffix or 'suffix-less'} file; score point clouds with "
            "`nbv-gym evaluate REFERENCE CANDIDATE`"
        )


def load_probability(path: Path, grid) -> np.ndarray:
    """The (X, Y, Z) float32 probability grid of a saved map (.npz) or a plain array (.npy)."""
    check_probability_file(path)
    if path.suffix == ".npy":
        prob = _load_npy(path)
        if prob.shape != grid.shape or not np.issubdtype(prob.dtype, np.floating):
            raise MetricInputError(
                f"{path}: expected a float probability grid of shape {grid.shape} (G's box at "
                f"0.1 m voxels), got {prob.dtype} {prob.shape}"
            )
        bad = ~((prob >= 0) & (prob <= 1))  # NaN too
        if bad.any():
            raise MetricInputError(
                f"{path}: probabilities must lie in [0, 1]; {int(bad.sum())} value(s) do not "
                f"(e.g. {float(prob[bad].flat[0])})"
            )
        return prob.astype(np.float32, copy=False)
    return load_map(path).probability(grid)


#: The largest grid ``evaluate`` scores, voxels: its arrays are dense (the map's log-odds and
#: probabilities, the ground truth, the per-cuboid work), measured at 2.3 GB peak for a
#: 900 × 1180 × 60 grid, about 30 bytes a voxel: some 4 GB at this size (a world some 150 m
#: across at 0.1 m voxels, 6 m high).
MAX_GRID_VOXELS = 1 << 27


def check_grid(grid, what: str, advice: str) -> None:
    """MetricInputError, naming ``what`` was to be scored, its grid and ``advice``, when
    ``grid`` has more than :data:`MAX_GRID_VOXELS` voxels (checked before allocating)."""
    count = int(np.prod(grid.shape, dtype=np.float64))
    if count <= MAX_GRID_VOXELS:
        return
    shape = " × ".join(map(str, grid.shape))
    raise MetricInputError(
        f"{what}: the grid to score is {shape} voxels of {grid.res:g} m ({count:,}; "
        f"{_extent(grid.low, grid.high)} m), more than the limit of {MAX_GRID_VOXELS:,} "
        f"(nbv_gym.metrics.evaluation.MAX_GRID_VOXELS: its arrays are dense); {advice}"
    )


def _extent(low, high) -> str:
    return "×".join(f"[{a:.1f}, {b:.1f}]" for a, b in zip(low, high, strict=True))


def world_inputs(map_path: Path, world: str):
    """The probability grid, bool ground truth and :class:`GridSpec` of a map scored against
    ``world``: over the box ``run`` scores it in — G's box (the default mapping config's)
    fitted to the world's window, at the map's 0.1 m voxels — so that a map of a world larger
    than the benchmark's 60 m scores as its run did."""
    from nbv_gym.mapping.state import MappingConfig
    from nbv_gym.worlds import load_world

    built = load_world(world)
    grid = MappingConfig().fitted(built.window_m).scored_grid()
    check_grid(grid, f"world {built.name}", "score a map of a smaller world")
    return load_probability(map_path, grid), built.ground_truth.occupancy(grid), grid


def load_ground_truth(path: Path, grid) -> np.ndarray:
    """The (X, Y, Z) bool ground truth of the ``.npy`` file ``path`` on ``grid``."""
    if not path.is_file():
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

    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]) if rows else [])
        writer.writeheader()
        writer.writerows(rows)


def empir3d_config(epsilon: float | None, region: float | None) -> Empir3DConfig:
    """The Empir3D config of the options given; the config's own value for each option left out."""
    given = {"epsilon_m": epsilon, "region_m": region}
    return Empir3DConfig(**{k: v for k, v in given.items() if v is not None})


#: Suffixes of the ground-truth point clouds ``evaluate --ground-truth`` scores against with
#: Alg. 1 (a ``.npy`` is a bool grid on the benchmark grid instead).
TRUTH_CLOUD_SUFFIXES = (".ply", ".pcd", ".xyz", ".txt", ".pts", ".csv", ".las", ".laz")


def alg1_inputs(map_path: Path, truth_path: Path, res: float = 0.1):
    """The probability grid, bool ground truth and :class:`GridSpec` of Alg. 1 of Aravecchia et
    al. (IROS 2023): the map's known voxels and the ground-truth cloud's occupied voxels on the
    lattice of ``res`` metres, compared over the 1 m cuboids that intersect the intersection of
    both grids' bounding boxes (a saved map's grid is its box; a cloud's, its known voxels'
    bounding box). The cuboids sit on the benchmark's lattice (G's: x, y on whole
    metres, z from 0.2 m), so an nbv-gym map scores as ``evaluate --world`` scores it.

    ``map_path``: a saved map (.npz), an OctoMap (.bt, .ot; the octomap extra) or a cloud of
    known voxel centres with a ``probability`` property (.ply, as ``nbv-gym export --min-p 0``
    writes); ``truth_path``: any point
    cloud (PLY, PCD, XYZ; LAS/LAZ with the las extra). A saved map of a scene world is in
    that world's frame: the cloud is taken in the scene file's frame (its units and up axis)
    and moved into the world's as the world's own ground truth was (:func:`_truth_voxels`)."""
    known, probability, box = _map_voxels(map_path, res)
    truth = _truth_voxels(truth_path, res, _map_frame(map_path))
    grid = alg1_grid(box, truth, res, map_path, truth_path)
    check_grid(
        grid, f"{map_path} against {truth_path}",
        "crop the map or the cloud to the part to compare",
    )  # fmt: skip
    offset = np.rint(np.asarray(grid.origin) / res).astype(np.int64)
    prob = np.full(grid.shape, 0.5, np.float32)
    inside = grid.contains(known - offset)
    prob[tuple((known - offset)[inside].T)] = probability[inside]
    gt = np.zeros(grid.shape, bool)
    hit = grid.contains(truth - offset)
    gt[tuple((truth - offset)[hit].T)] = True
    return prob, gt, grid


def alg1_grid(box: np.ndarray, truth: np.ndarray, res: float, map_path, truth_path):
    """The grid of whole benchmark cuboids over the intersection of the map grid's box ``box``
    (2, 3) (first and last voxel index) and the bounding box of the (k, 3) ``truth`` voxel
    indices; MetricInputError when they do not meet."""
    from nbv_gym.core.grid import GridSpec
    from nbv_gym.metrics.cuboids import CuboidConfig, benchmark_grid

    low = np.maximum(box[0], truth.min(axis=0))
    high = np.minimum(box[1], truth.max(axis=0))
    if np.any(low > high):
        raise MetricInputError(
            f"{map_path} and {truth_path} do not overlap: the map's grid spans "
            f"{_box(box, res)} m, the ground truth's {_box(truth, res)} m"
        )
    n = CuboidConfig().cuboid_voxels
    anchor = np.rint(np.asarray(benchmark_grid().low) / res).astype(np.int64)
    first = np.floor_divide(low - anchor, n) * n + anchor
    last = (np.floor_divide(high - anchor, n) + 1) * n + anchor
    return GridSpec.from_bounds(tuple(first * res), tuple(last * res), res)


def _box(voxels: np.ndarray, res: float) -> str:
    return _extent(voxels.min(axis=0) * res, (voxels.max(axis=0) + 1) * res)


def _map_voxels(path: Path, res: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(k, 3) int64 voxel indices and (k,) float32 probabilities of a map's known voxels, and
    (2, 3) the first and last voxel index of its grid: a saved map's box, a cloud's bounding
    box."""
    if not path.is_file():
        raise MetricInputError(f"{path}: the map file {missing_file(path)}")
    if path.suffix == ".npz":
        from nbv_gym.mapping.export import map_voxels

        occupancy = load_map(path)
        if not np.isclose(occupancy.grid.res, res):
            raise MetricInputError(f"{path}: a map of {occupancy.grid.res} m voxels, not {res} m")
        centres, probability = map_voxels(occupancy, 0.0)
        first = np.rint(np.asarray(occupancy.grid.origin) / res).astype(np.int64)
        box = np.stack([first, first + occupancy.grid.shape - 1])
    elif path.suffix == ".ply":
        centres, probability = _probability_cloud(path)
        box = None
    elif path.suffix in (".bt", ".ot"):
        centres, probability = _octomap_voxels(path, res)
        box = None
    else:
        raise MetricInputError(
            f"{path}: with a ground-truth cloud, --map takes a saved map (.npz), an OctoMap "
            "(.bt, .ot) or a cloud of known voxels with a probability property (.ply, nbv-gym "
            "export --min-p 0)"
        )
    if len(centres) == 0:
        raise MetricInputError(f"{path}: the map holds no known voxel")
    voxels = np.floor(centres / res).astype(np.int64)
    if not np.allclose(centres, (voxels + 0.5) * res, atol=1e-3 * res):
        raise MetricInputError(f"{path}: the points are not the centres of {res} m voxels")
    if box is None:
        box = np.stack([voxels.min(axis=0), voxels.max(axis=0)])
    return voxels, probability.astype(np.float32), box


def _octomap_voxels(path: Path, res: float) -> tuple[np.ndarray, np.ndarray]:
    """(k, 3) float64 centres of the ``res`` voxels of an OctoMap's leaves (a pruned leaf
    split into its voxels) and their (k,) float32 occupancy probabilities."""
    try:
        import pyoctomap
    except ImportError:
        raise MissingExtraError("pyoctomap", "octomap") from None
    tree = pyoctomap.OcTree(res)
    if path.suffix == ".bt":
        read = tree.readBinary(str(path))
    else:
        read = tree.read(str(path))
        tree = read if read is not None else tree
    if not read or not np.isclose(tree.getResolution(), res):
        raise MetricInputError(f"{path}: not a readable OctoMap of {res} m voxels")
    centres, probability = [], []
    for leaf in tree.begin_leafs():
        centre, size = np.asarray(leaf.getCoordinate(), float), float(leaf.getSize())
        n = max(1, round(size / res))
        steps = (np.arange(n) - (n - 1) / 2) * res
        block = np.stack(np.meshgrid(steps, steps, steps, indexing="ij"), -1).reshape(-1, 3)
        centres.append(centre + block)
        probability.append(np.full(len(block), leaf.current_node.getOccupancy(), np.float32))
    if not centres:
        return np.empty((0, 3)), np.empty(0, np.float32)
    return np.concatenate(centres), np.concatenate(probability)


def _probability_cloud(path: Path) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    try:
        cloud = trimesh.load(str(path), process=False)
        vertex = cloud.metadata["_ply_raw"]["vertex"]["data"]
        centres = np.column_stack([vertex[a] for a in "xyz"]).astype(np.float64)
        probability = np.asarray(vertex["probability"], np.float32)
    except (KeyError, ValueError, TypeError, IndexError) as error:
        raise MetricInputError(
            f"{path}: not a PLY of voxel centres with a 'probability' property ({error!r})"
        ) from None
    bad = ~((probability >= 0) & (probability <= 1))
    if bad.any():
        raise MetricInputError(f"{path}: {int(bad.sum())} probabilities outside [0, 1]")
    return centres, probability


def _map_frame(path: Path) -> dict:
    """The scene frame a saved map records ({} for other maps: a procedural world's, or files
    that are not nbv-gym maps)."""
    from nbv_gym.core.errors import DataFileError
    from nbv_gym.mapping.mapfile import recorded_frame

    if path.suffix != ".npz":
        return {}
    try:
        return recorded_frame(path)
    except DataFileError as error:
        raise MetricInputError(str(error)) from None


def _truth_voxels(path: Path, res: float, frame: dict) -> np.ndarray:
    """(k, 3) int64 unique voxel indices holding a point of the ground-truth cloud: in the
    world frame of ``frame`` (a scene world's file frame, said), as read without one."""
    from nbv_gym.core.errors import DataFileError
    from nbv_gym.core.progress import say
    from nbv_gym.worlds.scenes.clouds import cloud_voxels, read_cloud, world_voxels

    if not path.is_file():
        raise MetricInputError(f"{path}: the ground-truth file {missing_file(path)}")
    try:
        points = read_cloud(path)
    except DataFileError as error:
        raise MetricInputError(str(error)) from None
    if not frame:
        return cloud_voxels(points, res)
    moved = ", ".join(f"{0.0 - v:g}" for v in frame["offset_m"])  # 0.0 - 0.0: no "-0"
    say(
        f"the map is in its scene world's frame: {path} is read in the scene file's (scale "
        f"{frame['scale']:g}, up {frame['up']}) and moved by ({moved}) m into it"
    )
    return world_voxels(points, frame, res)
