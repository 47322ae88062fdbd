"""The Empir3D paper's ablation study (*Empir3D: A Framework for Multi-Dimensional Point Cloud Assessment*, §IV-A, Table I) on any reference point cloud.

Each of the eight ablations degrades the reference ``A`` into a candidate ``B``; ``B`` is scored
against ``A`` with :func:`nbv_gym.metrics.empir3d.empir3d` (Q_r, Q_a, Q_c, Q_t, Chamfer, Hausdorff).
The paper's claim: each ablation moves the metric of its own dimension — resolution → Q_r, accuracy
→ Q_a, coverage → Q_c, artifacts → Q_t — and leaves the others (nearly) alone.

Ablations (*ours* where the paper is terse): down-sampling keeps a seeded uniformly random subset of
75 % / 50 % of the points; noise adds N(0, σ²) to each coordinate; a crop keeps the points whose
coordinate along X (or Y) lies in the lowest 40 % of the cloud's extent; a shift adds +0.1 m in X, or
0.282 m along the XY diagonal (0.1994 m in X and in Y).

Verdict rule (*ours*): a metric "moved" when it dropped by at least :data:`MOVED` from its value on
the undegraded cloud (the reference against itself); an ablation moves its own metric "most" when that
drop is within :data:`TIE` of the largest of the four drops. Reproduced: moved and most; partly: moved
but another metric dropped more; not reproduced: its own metric did not move.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import cast

import numpy as np

from nbv_gym.core.arrays import FloatArray
from nbv_gym.metrics.empir3d import Empir3DConfig, empir3d
from nbv_gym.reporting.verdicts import NOT_REPRODUCED, PARTLY, REPRODUCED
from nbv_gym.studies import StudyError
from nbv_gym.studies.report import Verdict

SCORES = ("q_r", "q_a", "q_c", "q_t")
SCORE_LABELS = {"q_r": "Q_r", "q_a": "Q_a", "q_c": "Q_c", "q_t": "Q_t"}
#: The metric each dimension of degradation should move (the paper's claim).
TARGETS = {"resolution": "q_r", "accuracy": "q_a", "coverage": "q_c", "artifacts": "q_t"}
MOVED = 0.02
TIE = 0.005
#: Table I of *Empir3D: A Framework for Multi-Dimensional Point Cloud Assessment* (ε = 0.1 m): value → (D_c, D_h, Q_r, Q_a, Q_c, Q_t). D_c is the paper's sum.
PAPER_TABLE_I: dict[str, tuple[float, float, float, float, float, float]] = {
    "Uniform 75%": (504.91, 0.17, 0.87, 1.00, 0.93, 1.00),
    "Uniform 50%": (1488.057, 0.20, 0.71, 1.00, 0.79, 1.00),
    "σ = 0.01": (682.95, 0.55, 0.91, 0.84, 0.92, 0.77),
    "σ = 0.02": (2064.36, 0.1, 0.81, 0.73, 0.93, 0.80),
    "X, 40%": (1.59e8, 24.27, 1.00, 1.00, 0.40, 1.00),
    "Y, 40%": (1.38e8, 24.01, 1.00, 1.00, 0.42, 1.00),
    "X, +0.1m": (5846.90, 0.1, 0.99, 0.62, 0.79, 0.79),
    "XY, +0.282m": (2.63e4, 0.28, 0.98, 0.71, 0.62, 0.62),
}


def downsample(points: FloatArray, rng: np.random.Generator, fraction: float) -> FloatArray:
    """A uniformly random ``round(fraction · n)`` of the (n, 3) ``points``, in their order."""
    keep = rng.choice(len(points), size=round(fraction * len(points)), replace=False)
    return points[np.sort(keep)]


def add_noise(points: FloatArray, rng: np.random.Generator, sigma_m: float) -> FloatArray:
    """(n, 3) ``points`` plus independent N(0, σ²) on each coordinate, metres."""
    return points + rng.normal(0.0, sigma_m, points.shape)


def crop(points: FloatArray, rng: np.random.Generator, axis: int, fraction: float) -> FloatArray:
    """The (n, 3) ``points`` whose coordinate along ``axis`` lies in the lowest ``fraction`` of the
    cloud's extent along it (``rng`` unused: the crop is deterministic)."""
    low, high = points[:, axis].min(), points[:, axis].max()
    return points[points[:, axis] <= low + fraction * (high - low)]


def shift(points: FloatArray, rng: np.random.Generator, offset_m: tuple[float, ...]) -> FloatArray:
    """(n, 3) ``points`` translated by ``offset_m`` (3,) metres (``rng`` unused)."""
    return points + np.asarray(offset_m, dtype=np.float64)


@dataclass(frozen=True)
class Ablation:
    """One row of Table I: the ``dimension`` it degrades (a key of :data:`TARGETS`), its ``value``
    as printed in the paper, and ``degrade(points, rng) -> points``."""

    dimension: str
    value: str
    degrade: Callable[[FloatArray, np.random.Generator], FloatArray] = field(compare=False)

    @property
    def target(self) -> str:
        """The score this ablation should move most."""
        return TARGETS[self.dimension]


_DIAGONAL_M = 0.282 / math.sqrt(2.0)
ABLATIONS: tuple[Ablation, ...] = (
    Ablation("resolution", "Uniform 75%", partial(downsample, fraction=0.75)),
    Ablation("resolution", "Uniform 50%", partial(downsample, fraction=0.50)),
    Ablation("accuracy", "σ = 0.01", partial(add_noise, sigma_m=0.01)),
    Ablation("accuracy", "σ = 0.02", partial(add_noise, sigma_m=0.02)),
    Ablation("coverage", "X, 40%", partial(crop, axis=0, fraction=0.4)),
    Ablation("coverage", "Y, 40%", partial(crop, axis=1, fraction=0.4)),
    Ablation("artifacts", "X, +0.1m", partial(shift, offset_m=(0.1, 0.0, 0.0))),
    Ablation("artifacts", "XY, +0.282m", partial(shift, offset_m=(_DIAGONAL_M, _DIAGONAL_M, 0.0))),
)


@dataclass(frozen=True)
class AblationResult:
    """Scores of one degraded cloud: ``scores`` maps Q_r … Q_t (``q_r`` …) to [0, 1];
    ``chamfer_m``/``hausdorff_m`` in metres; ``n_points`` of the candidate."""

    ablation: Ablation | None
    scores: dict[str, float]
    chamfer_m: float
    hausdorff_m: float
    n_points: int

    @property
    def label(self) -> str:
        """The ablation's name for tables (``none (A vs A)`` for the baseline)."""
        return "none (A vs A)" if self.ablation is None else self.ablation.value


def score(
    reference: FloatArray, candidate: FloatArray, config: Empir3DConfig, ablation: Ablation | None
) -> AblationResult:
    """Empir3D of ``candidate`` (m, 3) against ``reference`` (k, 3) as an :class:`AblationResult`."""
    if len(candidate) == 0:
        raise StudyError(
            f"ablation {ablation.value if ablation else 'none'} left no point; use a larger cloud"
        )
    result = empir3d(reference, candidate, config, distances=True)
    scores = {name: float(getattr(result, name)) for name in SCORES}
    # distances=True: both distances are set
    chamfer, hausdorff = cast(float, result.chamfer_m), cast(float, result.hausdorff_m)
    return AblationResult(ablation, scores, chamfer, hausdorff, len(candidate))


def run_ablations(
    reference: FloatArray,
    config: Empir3DConfig,
    rng: np.random.Generator,
    ablations: tuple[Ablation, ...] = ABLATIONS,
    progress: Callable[[str], None] | None = None,
) -> tuple[AblationResult, list[AblationResult]]:
    """The baseline (reference against itself) and one result per ablation, in order; each
    ablation draws from its own child of ``rng``, so results do not depend on the order."""
    reference = np.asarray(reference, dtype=np.float64)
    children = rng.spawn(len(ablations))
    baseline = score(reference, reference, config, None)
    results = []
    for ablation, child in zip(ablations, children, strict=True):
        if progress:
            progress(ablation.value)
        results.append(score(reference, ablation.degrade(reference, child), config, ablation))
    return baseline, results


def drops(scores: dict[str, float], baseline: dict[str, float]) -> dict[str, float]:
    """How much each score fell from its ``baseline`` value (positive = worse)."""
    return {name: baseline[name] - scores[name] for name in SCORES}


def moved_most(fallen: dict[str, float], target: str) -> tuple[bool, bool]:
    """(``target`` moved by at least :data:`MOVED`, its drop is the largest within :data:`TIE`)."""
    return fallen[target] >= MOVED, fallen[target] >= max(fallen.values()) - TIE


def classify(fallen: dict[str, float], target: str) -> str:
    """The verdict of one ablation from its score drops (see the module docstring)."""
    moved, most = moved_most(fallen, target)
    if moved and most:
        return REPRODUCED
    return PARTLY if moved else NOT_REPRODUCED


def verdicts(baseline: AblationResult, results: list[AblationResult]) -> list[Verdict]:
    """One verdict per ablation: does it move its own metric most, as Table I reports?"""
    rows = []
    for result in results:
        ablation = result.ablation
        if ablation is None:  # the baseline (A vs A) has no verdict
            continue
        target = ablation.target
        paper = dict(zip(SCORES, PAPER_TABLE_I[ablation.value][2:], strict=True))
        ours_fallen = drops(result.scores, baseline.scores)
        rows.append(
            Verdict(
                claim=f"{ablation.dimension} ({ablation.value}) moves {SCORE_LABELS[target]} most",
                paper=_describe(paper, drops(paper, dict.fromkeys(SCORES, 1.0)), target),
                ours=_describe(result.scores, ours_fallen, target),
                verdict=classify(ours_fallen, target),
            )
        )
    return rows


def _describe(scores: dict[str, float], fallen: dict[str, float], target: str) -> str:
    """ "Q_r 0.87 (Q_a 1.00, …); most moved: Q_r"."""
    others = ", ".join(f"{SCORE_LABELS[n]} {scores[n]:.2f}" for n in SCORES if n != target)
    top = max(fallen.values())
    most = "/".join(SCORE_LABELS[n] for n in SCORES if fallen[n] >= top - TIE and top >= MOVED)
    return f"{SCORE_LABELS[target]} {scores[target]:.2f} ({others}); most moved: {most or 'none'}"


def surface_samples(world, count: int, rng: np.random.Generator) -> FloatArray:
    """(count, 3) float64 points drawn uniformly (by area) on the asset surfaces of ``world``
    (a :class:`nbv_gym.worlds.World`; the ground plane is left out), metres."""
    import trimesh

    if count < 2:
        raise StudyError(f"need at least 2 surface points, got {count}")
    mesh = trimesh.Trimesh(world.vertices, world.faces[: world.asset_faces], process=False)
    points, _ = trimesh.sample.sample_surface(mesh, count, seed=rng)
    return np.asarray(points, dtype=np.float64)
