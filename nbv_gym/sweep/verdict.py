"""The reproduction verdict: one row per claim of *Next-Best-View selection from observation
viewpoint statistics* (Aravecchia, Richard, Clausel, Pradalier; IROS 2023), with the paper's
statement, the figure computed from the sweep's tables, the sample size, the test, its p-value,
the effect with its interval, and a verdict: reproduced, partly, not, inconclusive (n = …), no
paper value (ours alone: the paper's figure is not legible) or no data.

Nothing here is written by hand about the outcome: every figure and verdict is computed from
``runs.csv``, ``steps.csv`` and ``cuboids.parquet``. Oracle policies are left out.

Claims and rules (α = 0.05):

- **Fig. 1 trends**, per statistic and metric: over the observed cuboids (n_obs ≥ 1) at noise
  level 1, the Spearman correlation between the statistic and cov (U_occ) or L1 (U_empty), per
  asset type. Expected sign: cov rises with n_obs, n_Ω, σ_θ and falls with r_min; L1 the
  opposite. Reproduced if every asset type has the expected sign with p < 0.05; partly if some
  do and the mean ρ has the expected sign; not otherwise. This test, the paper's, takes tens of
  thousands of cuboids from a few dozen runs as independent (hence p < 1e-16); a run-level test
  stands beside it (:func:`run_level_p`: each run's ρ, Wilcoxon signed-rank across runs), shown,
  not used by the verdict.
- **Table II**, per statistic and metric: our share of tests with p < 0.05 next to the paper's
  (one Mann–Whitney test per run, on that run's cuboids, as the paper). Reproduced if ours is
  within 0.15 of the paper's or above it, partly if within 0.30, else not; *no paper value*
  where the paper's figure is not legible (ours is shown alone).
- **Fig. 2 ordering**, per NBV policy and baseline: the pair's runs are paired by world, noise
  level and repeat; at each of 50, 60 and 70 % discovered the differences of Q_paper (NBV −
  baseline) over all asset types get a one-sided Wilcoxon signed-rank test (H1: NBV higher), and
  the p-values of every pair and fraction — the Fig. 2 family — are Holm-adjusted together.
  *inconclusive (n = …)* when even the most extreme sample could not give an adjusted p < 0.05
  (:func:`~nbv_gym.reporting.inference.smallest_p_wilcoxon` × family size); *not* when the mean
  difference is not positive (a wrong sign is never *partly*); *reproduced* when NBV is
  significantly higher at every fraction and no asset × fraction cell has it significantly
  lower; *partly* when it is significantly higher at some fraction; *not* otherwise. The cells
  significantly higher and lower (per asset type and fraction, uncorrected) are counted and
  shown.
- **"More so in harder worlds"**: per pairing unit the mean Q_paper advantage of the NBV
  policies over the baselines, against its asset type's difficulty rank (cuboids < crosses <
  helicoids < trees): one-sided Spearman permutation test. Reproduced if ρ > 0 with p < 0.05,
  the hardest type's advantage exceeds the easiest's and every type's advantage is positive;
  partly if so except that an easier type's advantage is not positive; inconclusive if n is too
  small; not otherwise (negative advantages that grow are *not*).
- **Budget protocol** (not a claim of the paper: its claim at equal scans, travel free): each NBV policy
  against each baseline on Q after 5 and 12 scans, over every noise level, paired and tested
  like Fig. 2 (its own Holm family), with the same rules. A run that stopped earlier (the paper's
  task ends at the discovered target) holds its final Q (:mod:`nbv_gym.metrics.effort`).

The comparisons run once per visibility model the NBV policies fix (``nbv-nobs@fov``), each
model its own family, so ``nbv-visibility.toml`` gets one Fig. 2 verdict per model.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from nbv_gym.reporting.inference import (
    Interval,
    bootstrap_mean,
    can_reach,
    holm,
    smallest_p_spearman,
    smallest_p_wilcoxon,
)
from nbv_gym.reporting.verdicts import (
    NO_DATA,
    NO_PAPER_VALUE,
    NOT_REPRODUCED,
    PARTLY,
    REPRODUCED,
    inconclusive,
)
from nbv_gym.sweep.effort import q_after_scans
from nbv_gym.worlds import ASSET_TYPES

#: The paper's Table II (simulation, 162 runs): share of tests with p < 0.05. σ_θ's L1 value is
#: not legible in the paper's text.
PAPER_TABLE2 = {
    ("n_obs", "cov"): 0.74, ("n_obs", "l1"): 0.90,
    ("r_min", "cov"): 0.89, ("r_min", "l1"): 1.00,
    ("n_omega", "cov"): 0.74, ("n_omega", "l1"): 0.87,
    ("sigma_theta", "cov"): 0.88, ("sigma_theta", "l1"): np.nan,
}  # fmt: skip
#: Expected sign of the correlation between each statistic and cov (L1: the opposite).
COV_SIGN = {"n_obs": 1, "r_min": -1, "n_omega": 1, "sigma_theta": 1}
FRACTIONS = (0.5, 0.6, 0.7)
BASELINES = ("random-frontier", "closest-frontier", "random-free")
#: Numbers of scans of the budget-protocol rows.
SCANS = (5, 12)
ALPHA = 0.05
WILCOXON = "one-sided Wilcoxon signed-rank (H1: NBV higher), paired by world·noise·repeat"
#: The columns of the verdict table (``model``: the visibility model, "" for none).
COLUMNS = ["claim", "paper", "n", "test", "p", "effect", "ours", "verdict", "model"]
#: How each family of comparison rows reads.
COMPARISONS: dict[str, dict[str, Any]] = {
    "fig2": {
        "claim": "Fig. 2: {policy} above {baseline}",
        "paper": "NBV curves higher than the baselines' (Q_paper vs discovered)",
        "quantity": "ΔQ_paper",
        "points": FRACTIONS,
        "point": "{:.0%}",
    },
    "budget": {
        "claim": "Budget: {policy} above {baseline}",
        "paper": "(not in the paper) the Fig. 2 claim at equal scans, travel free: Q after 5 and 12 scans",
        "quantity": "ΔQ",
        "points": SCANS,
        "point": "{} scans",
    },
}


def verdict(hits: int, total: int) -> str:
    """``reproduced`` if every one of ``total`` cases holds, ``partly`` if some, else ``not``."""
    if total == 0:
        return NO_DATA
    return REPRODUCED if hits == total else (PARTLY if hits else NOT_REPRODUCED)


def trend_rows(cuboids) -> list[dict]:
    """Fig. 1's trends: one row per statistic and metric (module docstring)."""
    from scipy.stats import spearmanr

    cuboids = cuboids[cuboids["n_obs"] >= 1]
    rows = []
    for statistic, sign in COV_SIGN.items():
        for metric, column, expected in (("cov", "cov_q", sign), ("L1", "l1", -sign)):
            parts, hits, n = [], 0, 0
            rhos: list[float] = []
            ps: list[float] = []
            run_ps: list[float] = []
            for asset in [a for a in ASSET_TYPES if a in set(cuboids["asset"])]:
                occ = cuboids["u_occ"].to_numpy(bool) == (metric == "cov")
                pick = cuboids[occ & (cuboids["asset"] == asset).to_numpy()]
                result = spearmanr(pick[statistic], pick[column], nan_policy="omit")
                rho, p = float(result.statistic), float(result.pvalue)
                hits += bool(np.sign(rho) == expected and p < ALPHA)
                parts.append(f"{asset} {rho:+.2f}")
                rhos, ps, n = [*rhos, rho], [*ps, p], n + len(pick)
                if "key" in pick.columns:
                    run_ps.append(run_level_p(pick, statistic, column))
            word = "rises" if expected > 0 else "falls"
            outcome = verdict(hits, len(parts))
            if outcome == PARTLY and not np.nanmean(rhos) * expected > 0:
                outcome = NOT_REPRODUCED  # a wrong-sign mean is never partly
            runs = f"; runs: largest {_p(max(run_ps))}" if run_ps else ""
            rows.append(
                {
                    "claim": f"Fig. 1: {metric} {word} with {statistic}",
                    "paper": f"{metric} {word} with {statistic} (all asset types)",
                    "n": f"{n} cuboids" + (f", {cuboids['key'].nunique()} runs" if run_ps else ""),
                    "test": TREND_TEST,
                    "p": f"cuboids: largest {_p(max(ps))}{runs}" if ps else "—",
                    "effect": f"mean ρ {np.nanmean(rhos):+.2f}" if rhos else "—",
                    "ours": "Spearman ρ: " + ", ".join(parts),
                    "verdict": outcome,
                }
            )
    return rows


#: How the Fig. 1 rows test: the paper's cuboid-level test decides; the run-level one stands beside.
TREND_TEST = (
    "two-sided Spearman ρ per asset type over the pooled cuboids — cuboid-level, the cuboids "
    "taken as independent as in the paper; the verdict follows it. Beside it (runs:), run-level: "
    "each run's ρ, two-sided Wilcoxon signed-rank test of the runs' ρ against 0 (runs as units)"
)


def run_level_p(cuboids, statistic: str, column: str) -> float:
    """The run-level test of a Fig. 1 trend: Spearman's ρ of ``statistic`` and ``column`` within
    each run (``key``; runs with fewer than 3 cuboids or a constant column are left out), then
    the two-sided Wilcoxon signed-rank test of those ρ against 0 — the runs, not the cuboids, as
    the independent units. NaN with fewer than 2 runs."""
    from scipy.stats import spearmanr, wilcoxon

    rhos = []
    for _, run in cuboids.groupby("key", sort=False):
        run = run[[statistic, column]].dropna()
        if len(run) >= 3 and run[statistic].nunique() > 1 and run[column].nunique() > 1:
            rhos.append(float(spearmanr(run[statistic], run[column]).statistic))
    rhos_array = np.asarray(rhos)
    if rhos_array.size < 2 or not np.any(rhos_array):
        return np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy's note on ties and small samples
        return float(wilcoxon(rhos_array).pvalue)


def table2_rows(shares) -> list[dict]:
    """Table II: one row per statistic and metric, ``shares`` as :func:`~nbv_gym.sweep.tables.table2`."""
    rows = []
    for (statistic, metric), paper in PAPER_TABLE2.items():
        ours = float(shares.loc[statistic, metric]) if statistic in shares.index else np.nan
        if not np.isfinite(ours):
            outcome = NO_DATA
        elif not np.isfinite(paper):
            outcome = NO_PAPER_VALUE  # ours is there; the paper's value is not legible
        else:
            gap = paper - ours
            outcome = REPRODUCED if gap <= 0.15 else (PARTLY if gap <= 0.30 else NOT_REPRODUCED)
        rows.append(
            {
                "claim": f"Table II: {statistic} indicates {metric}",
                "paper": "—" if not np.isfinite(paper) else f"{paper:.2f} of tests p < 0.05",
                "test": "share of the per-run Mann–Whitney tests of Table I with p < 0.05 (each "
                "test takes a run's cuboids as independent, as the paper does)",
                "ours": "—" if not np.isfinite(ours) else f"{ours:.2f}",
                "verdict": outcome,
            }
        )
    return rows


def paired_at_fractions(runs, steps, column: str = "q_paper"):
    """Per run: ``column`` interpolated at :data:`FRACTIONS` of the discovered fraction. A
    DataFrame indexed like ``runs`` with one column per fraction (NaN where not reached)."""
    import pandas as pd

    from nbv_gym.reporting.inference import q_curve

    by_key = {key: group.sort_values("step") for key, group in steps.groupby("key", sort=False)}
    grid = np.asarray(FRACTIONS)
    values = [
        q_curve(by_key[k]["discovered"].to_numpy(), by_key[k][column].to_numpy(), grid)
        if k in by_key else np.full(len(grid), np.nan)
        for k in runs["key"]
    ]  # fmt: skip
    table = np.vstack(values) if values else np.empty((0, len(grid)))  # no runs: no rows
    return pd.DataFrame(table, index=runs.index, columns=list(FRACTIONS))


@dataclass(frozen=True)
class OneSided:
    """A paired comparison "A above B" on ``n`` differences A − B: their mean with its 95 %
    bootstrap interval, the one-sided Wilcoxon signed-rank p of "A higher" (``p_above``) and of
    "A lower" (``p_below``; NaN when every difference is 0), and how many differences are not 0
    (the test's sample: it drops zeros)."""

    effect: Interval
    p_above: float
    p_below: float
    nonzero: int

    @property
    def n(self) -> int:
        """Number of pairs the test compared."""
        return self.effect.n


def one_sided(diff: np.ndarray, rng: np.random.Generator | None = None) -> OneSided:
    """The :class:`OneSided` comparison of the (n,) paired differences ``diff`` (NaN dropped);
    without ``rng`` the interval is not computed (NaN bounds)."""
    from scipy.stats import wilcoxon

    diff = np.asarray(diff, float)
    diff = diff[np.isfinite(diff)]
    nonzero = int(np.count_nonzero(diff))
    p_above = p_below = np.nan
    if nonzero:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # scipy's note on ties and small samples
            p_above = float(wilcoxon(diff, alternative="greater").pvalue)
            p_below = float(wilcoxon(diff, alternative="less").pvalue)
    if rng is None:
        mean = float(diff.mean()) if diff.size else np.nan
        return OneSided(Interval(mean, np.nan, np.nan, diff.size), p_above, p_below, nonzero)
    return OneSided(bootstrap_mean(diff, rng), p_above, p_below, nonzero)


def comparison_verdict(tests: list[OneSided], p_holm: list[float], family: int, below: int) -> str:
    """The verdict of "A above B" tested at several points (fractions or scan counts), each
    test's p Holm-adjusted (``p_holm``) in a ``family`` of that many tests; ``below`` cells show A
    significantly lower. *inconclusive (n = …)* if no test can reach p < α; *not* if the mean
    effect is not positive (a wrong sign never reads partly); *reproduced* if A is
    significantly higher at every point and nowhere significantly lower; *partly* if higher at
    some point; else *not*."""
    n = max((t.nonzero for t in tests), default=0)
    if not any(t.n for t in tests):
        return NO_DATA
    if not can_reach(smallest_p_wilcoxon(n, "greater"), family, ALPHA):
        return inconclusive(max(t.n for t in tests))
    if not pooled_mean(tests) > 0:
        return NOT_REPRODUCED
    higher = [bool(p < ALPHA and t.effect.mean > 0) for t, p in zip(tests, p_holm, strict=True)]
    if all(higher) and below == 0:
        return REPRODUCED
    return PARTLY if any(higher) else NOT_REPRODUCED


def pooled_mean(tests: list[OneSided]) -> float:
    """The mean difference over every pair of ``tests`` (each test's mean weighted by its n);
    NaN without pairs."""
    used = [t for t in tests if t.n and np.isfinite(t.effect.mean)]
    total = sum(t.n for t in used)
    return sum(t.effect.mean * t.n for t in used) / total if total else np.nan


def model_of(policy: str) -> str:
    """The visibility model an NBV policy name fixes (``nbv-nobs@fov`` → ``fov``), "" if none."""
    return policy.partition("@")[2]


def comparison_rows(runs, values, kind: str, rng: np.random.Generator):
    """The rows of one family of comparisons "each ``nbv-*`` policy above each baseline":
    ``values`` (a DataFrame indexed like ``runs``, one column per point — discovered fractions
    for ``kind = "fig2"``, numbers of scans for ``"budget"``) paired by world, noise level and
    repeat, tested at each point over all asset types, Holm-adjusted over every test of the
    family; per asset type × point the cells significantly higher or lower (uncorrected, shown,
    not decisive). Also the mean advantage per asset type (the harder-worlds claim's input)."""
    table = runs[["world", "noise", "repeat", "asset", "policy"]].join(values)
    wide = table.pivot_table(
        index=["world", "noise", "repeat", "asset"], columns="policy", dropna=False
    )
    present = set(runs["policy"])
    pairs = [
        (policy, baseline)
        for policy in sorted(p for p in present if p.startswith("nbv-"))
        for baseline in BASELINES
        if baseline in present
    ]
    assets = [a for a in ASSET_TYPES if a in set(runs["asset"])]
    found = []
    advantage: dict[str, list[float]] = {}
    for policy, baseline in pairs:
        tests, above, below, cells = [], 0, 0, 0
        for point in values.columns:
            pair = wide[point].reindex(columns=[policy, baseline]).dropna()
            diff = (pair[policy] - pair[baseline]).to_numpy()
            tests.append(one_sided(diff, rng))
            for asset in assets:
                part = diff[pair.index.get_level_values("asset") == asset]
                if len(part) < 2:
                    continue
                cells += 1
                advantage.setdefault(asset, []).append(part.mean())
                if np.any(part != 0):
                    cell = one_sided(part)
                    above += bool(cell.p_above < ALPHA)
                    below += bool(cell.p_below < ALPHA)
        found.append((policy, baseline, tests, (above, below, cells)))
    p_holm = holm(np.array([t.p_above for *_, tests, _ in found for t in tests], float))
    family = int(np.isfinite(p_holm).sum())
    rows, k = [], len(values.columns)
    for i, (policy, baseline, tests, counts) in enumerate(found):
        adjusted = list(p_holm[i * k : (i + 1) * k])
        rows.append(_comparison_row(kind, policy, baseline, tests, adjusted, family, counts))
    return rows, {asset: float(np.mean(v)) for asset, v in advantage.items()}


def _comparison_row(kind, policy, baseline, tests, p_holm, family, counts) -> dict:
    above, below, cells = counts
    spec = COMPARISONS[kind]
    ns = sorted({t.n for t in tests})
    ours = f"mean {spec['quantity']} over all pairs {pooled_mean(tests):+.4f}"
    if kind == "fig2":
        ours += (
            f"; asset × fraction cells higher (p < 0.05, uncorrected) {above}/{cells}, "
            f"lower {below}/{cells}"
        )
    points = [spec["point"].format(p) for p in spec["points"]]
    return {
        "claim": spec["claim"].format(policy=policy, baseline=baseline),
        "paper": spec["paper"],
        "n": "—" if not ns else (f"{ns[0]}" if len(ns) == 1 else f"{ns[0]}–{ns[-1]}"),
        "test": WILCOXON,
        "p": "; ".join(f"{pt}: {_p(p)}" for pt, p in zip(points, p_holm, strict=True)),
        "effect": "; ".join(
            f"{pt}: {_interval(t.effect)}" for pt, t in zip(points, tests, strict=True)
        ),
        "ours": ours,
        "verdict": comparison_verdict(tests, p_holm, family, below),
    }


def harder_row(units, rng: np.random.Generator | None = None) -> dict:
    """ "More so in harder worlds": the NBV policies' mean advantage over the baselines per
    pairing unit (world, noise level, repeat; a DataFrame with ``asset`` and ``advantage``)
    against its asset type's difficulty rank (cuboids < crosses < helicoids < trees), by
    Spearman's ρ with a one-sided permutation test (exact for n ≤ 7). *inconclusive* if n is too
    small for p < α; *reproduced* if ρ > 0 significantly, the hardest type's advantage exceeds
    the easiest's and every type's advantage is positive; *partly* if so but an easier type's
    advantage is not positive; *not* otherwise."""
    units = units[np.isfinite(units["advantage"])]
    assets = [a for a in ASSET_TYPES if a in set(units["asset"])]
    means = {a: float(units.loc[units["asset"] == a, "advantage"].mean()) for a in assets}
    row = {
        "claim": "Fig. 2: the NBV advantage grows with difficulty",
        "paper": "particularly true when the difficulty in the scene increases",
        "n": f"{len(units)}",
        "test": "one-sided Spearman ρ (permutation), advantage per world·noise·repeat vs rank",
        "p": "—",
        "effect": "—",
        "ours": "mean ΔQ_paper (NBV − baselines) per asset type: "
        + ", ".join(f"{a} {v:+.4f}" for a, v in means.items()),
    }
    if len(assets) < 2:
        return {**row, "verdict": NO_DATA}
    rank = units["asset"].map({a: ASSET_TYPES.index(a) for a in assets}).to_numpy(float)
    rho, p = spearman_greater(rank, units["advantage"].to_numpy(float), rng)
    row.update(p=_p(p), effect=f"ρ {rho:+.2f}")
    values = list(means.values())
    if not can_reach(smallest_p_spearman(len(units), "greater")):
        outcome = inconclusive(len(units))
    elif rho <= 0 or not p < ALPHA or values[-1] <= values[0] or values[-1] <= 0:
        outcome = NOT_REPRODUCED
    else:
        outcome = REPRODUCED if min(values) > 0 else PARTLY
    return {**row, "verdict": outcome}


def spearman_greater(x, y, rng: np.random.Generator | None = None) -> tuple[float, float]:
    """Spearman's ρ of (n,) ``x`` and ``y`` and the one-sided (ρ > 0) permutation p-value
    (``scipy.stats.permutation_test``: exact for n ≤ 7, else 9 999 random pairings)."""
    from scipy.stats import permutation_test, rankdata

    rx, ry = rankdata(x), rankdata(y)
    if np.ptp(rx) == 0 or np.ptp(ry) == 0:
        return np.nan, np.nan
    rx = (rx - rx.mean()) / np.linalg.norm(rx - rx.mean())

    def rho(ranks, axis=-1):
        centred = ranks - ranks.mean(axis=axis, keepdims=True)
        return (centred @ rx) / np.linalg.norm(centred, axis=axis)

    result = permutation_test(
        (ry,), rho, permutation_type="pairings", alternative="greater", vectorized=True,
        n_resamples=9_999, rng=rng or np.random.default_rng(0),
    )  # fmt: skip
    return float(result.statistic), float(result.pvalue)


def advantage_units(runs, at):
    """Per pairing unit (world, noise level, repeat): its asset type and the mean of every
    ``nbv-*`` − baseline difference of the values ``at`` (indexed like ``runs``). A DataFrame."""
    table = runs[["world", "noise", "repeat", "asset", "policy"]].join(at)
    long = table.melt(id_vars=["world", "noise", "repeat", "asset", "policy"], var_name="point")
    wide = long.pivot_table(
        index=["world", "noise", "repeat", "asset", "point"], columns="policy", values="value"
    )
    nbv = [p for p in wide.columns if p.startswith("nbv-")]
    baselines = [b for b in BASELINES if b in wide.columns]
    diffs = [wide[p] - wide[b] for p in nbv for b in baselines]
    if not diffs:
        return wide.reset_index()[["asset"]].assign(advantage=np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # points no pair covers: NaN
        per_point = np.nanmean(np.vstack(diffs), axis=0)
    frame = wide.index.to_frame(index=False).assign(advantage=per_point)
    return frame.groupby(["world", "noise", "repeat", "asset"], as_index=False)["advantage"].mean()


def verdict_table(runs, steps, cuboids, shares, rng: np.random.Generator | None = None):
    """All rows (module docstring) as a DataFrame with columns :data:`COLUMNS`. ``cuboids``
    (noise 1) and ``shares`` (Table II) may be None when the sweep has no per-cuboid table. The
    comparisons run once per visibility model the ``nbv-*`` policies fix (``@model``), each
    model its own family."""
    import pandas as pd

    rng = rng or np.random.default_rng(0)
    rows = []
    if cuboids is not None:
        rows += trend_rows(cuboids)
    if shares is not None:
        rows += table2_rows(shares)
    fig2_runs = runs[runs["noise"] == 0] if (runs["noise"] == 0).any() else runs
    for model, group in _model_groups(fig2_runs):
        at = paired_at_fractions(group, steps)
        ordering, _ = comparison_rows(group, at, "fig2", rng)
        rows += _tagged(ordering + [harder_row(advantage_units(group, at), rng)], model)
    for model, group in _model_groups(runs):
        budget, _ = comparison_rows(group, q_after_scans(group, steps, SCANS), "budget", rng)
        rows += _tagged(budget, model)
    return pd.DataFrame(rows, columns=COLUMNS).astype(object).fillna("—")


def _model_groups(runs):
    """(model, runs of the baselines and of the NBV policies fixing that model), per visibility
    model present ("" for policies that fix none)."""
    nbv = [p for p in dict.fromkeys(runs["policy"]) if p.startswith("nbv-")]
    models = list(dict.fromkeys(model_of(p) for p in nbv)) or [""]
    baseline = runs["policy"].isin(BASELINES)
    for model in models:
        mine = runs["policy"].isin([p for p in nbv if model_of(p) == model])
        yield model, runs[baseline | mine]


def _tagged(rows: list[dict], model: str) -> list[dict]:
    """``rows`` with their claim tagged by the visibility ``model`` (unchanged for "")."""
    if not model:
        return rows
    return [{**r, "claim": f"[{model}] {r['claim']}", "model": model} for r in rows]


def _interval(interval: Interval) -> str:
    if not np.isfinite(interval.mean):
        return "—"
    return f"{interval.mean:+.4f} [{interval.low:+.4f}, {interval.high:+.4f}]"


def _p(value: float) -> str:
    if not np.isfinite(value):
        return "—"
    return "< 1e-16" if value < 1e-16 else f"{value:.3g}"
