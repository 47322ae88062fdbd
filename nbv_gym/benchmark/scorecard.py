"""The scorecard of a policy on a suite: what ran, who ran it, every run's figures and the
aggregates in the rliable recipe, as strict JSON (``scorecard.json``) and a short Markdown summary
(``scorecard.md``).

Fields (the JSON schema :data:`~nbv_gym.benchmark.validation.SCHEMA_PATH` ships beside this module
and fixes them; every loaded card is checked against it):

- ``format``: ``"nbv-gym scorecard"``; ``protocol_version``: :data:`~nbv_gym.benchmark.suites.PROTOCOL_VERSION`;
- ``suite``: name, content hash, seed and its parts (split, task, metric, worlds, noise, repeats);
- ``nbv_gym``: version and git commit (``unknown`` outside a checkout); ``versions``: Python and
  the libraries;
- ``policy``: the name scored, its class, ``oracle`` (it reads privileged values: ranked apart)
  and ``code_hash``, the SHA-256 of the file that defines it — the module source of a registered or
  ``module:Class`` policy, the model file of a trained agent (``hashed_file`` names it);
- ``runs``: one object per run: split, task, world, asset, noise, repeat, seed, steps, end reason,
  Q and Q_paper at the end, Q_paper at 70 % discovered, discovered fraction, path length (m),
  the robot's elapsed time under the effort model (s), Q over effort (``q_time`` on
  :data:`~nbv_gym.benchmark.curves.TIME_GRID_S`, ``q_path`` on
  :data:`~nbv_gym.benchmark.curves.PATH_GRID_M`; ``q_time_auc``: the normalised area under Q(t)
  over the time task's budget, null in the other tasks), decision time (mean seconds of the
  policy's ``act`` per step) and the episode's wall time; a team run (the team suite's parts
  name their ``robots``) adds ``time_to_q_s``, ``per_robot``, ``overlap_rate``,
  ``longest_path_m`` and ``contribution_spread`` and keeps ``q_time`` on
  :data:`~nbv_gym.benchmark.curves.TEAM_TIME_GRID_S` (:mod:`nbv_gym.benchmark.teamrun`);
- ``aggregates``: per split, the split's score (``metric``: the area under Q(t) for the time
  task, Q after the budget for the budget task, Q_paper at 70 % for the explore task) over all
  its runs (``all``) and per asset type (``by_asset``): the interquartile mean and the mean,
  each with its 95 % interval under the stratified bootstrap (runs resampled within each world ×
  noise level; :mod:`nbv_gym.reporting.inference`), and the optimality gap ``mean(max(1 − score, 0))``
  with its interval — the target 1 is a perfect map (every ground-truth voxel covered, every
  empty cuboid at the clamping floor); ``means``: plain means of the other figures; ``effort``:
  the same summaries of Q at matched path (25, 50, 100, 200 m), of Q at the time budget (time
  task), the mean elapsed time and the mean Q(t) and Q(path) curves with their interquartile
  bands. :func:`aggregate` computes all of a split's aggregates;
- ``created`` and ``timing`` (wall time, workers): the only fields, with the per-run times, that
  differ between two scorings of the same policy.

JSON has no NaN: an undefined number is ``null``. It means: Q_paper at 70 % of a run that ended
before 70 % was discovered; a decision time of a policy that made no decision or could not be
timed; any statistic over no value (a summary with ``n`` = 0).
"""

from __future__ import annotations

import hashlib
import math
import re
import time
from collections.abc import Sequence
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from nbv_gym.benchmark.cardtypes import (
    Aggregate,
    Band,
    Effort,
    Figure,
    Metric,
    PartDescription,
    PolicyEntry,
    RunEntry,
    Scorecard,
    Summary,
    Timing,
    value_of,
)
from nbv_gym.benchmark.suites import METRIC_LABELS, PROTOCOL_VERSION, Suite
from nbv_gym.benchmark.validation import (  # noqa: F401 (SCHEMA_PATH: re-exported)
    SCHEMA_PATH,
    ScorecardError,
    validate_scorecard,
)
from nbv_gym.core.jsonfiles import dumps_json
from nbv_gym.reporting.formatting import estimate_text, number_text, undefined

FORMAT = "nbv-gym scorecard"
#: The optimality gap's target score: a perfect map.
TARGET_SCORE = 1.0
#: Figures of a run whose plain means the aggregates carry.
MEAN_FIGURES = (
    "q",
    "q_paper",
    "q_paper_70",
    "discovered",
    "path_length_m",
    "steps",
    "decision_time_s",
)
#: Figures of a team protocol's run whose plain means its split's aggregates add
#: (``time_to_q_s``: over the runs that reached the Q target).
TEAM_MEAN_FIGURES = ("overlap_rate", "longest_path_m", "contribution_spread", "time_to_q_s")
#: Seed of the bootstrap (a scorecard is the same whenever its runs are).
BOOTSTRAP_SEED = 0
#: The time task's score (:data:`~nbv_gym.benchmark.suites.TASK_METRICS`).
TIME_METRIC = "q_time_auc"


def policy_identity(name: str) -> PolicyEntry:
    """The ``policy`` entry of a scorecard for the policy ``name`` (loaded once here, so a bad
    name fails before any run): name, class, oracle flag and the hash of its code or model
    (:func:`policy_file`)."""
    from nbv_gym.policies import is_oracle, load_policy, policy_name

    policy = load_policy(name)
    path = policy_file(name)
    return {
        "name": name,
        "class": policy_name(policy),
        "oracle": is_oracle(policy),
        "hashed_file": path.name if path else None,
        "code_hash": file_hash(path) if path else None,
    }


def policy_file(name: str) -> Path | None:
    """The file that defines the policy ``name``: the model file of a shipped model or
    ``sb3:PATH``, else the source of the module of its ``module:Class`` (registered names
    resolved, ``@visibility`` suffixes ignored); None if the module has no source file."""
    import importlib.util

    from nbv_gym.policies import MODELS, POLICIES, SB3_PREFIX, model_path

    if name in MODELS:
        return model_path(name)
    if name.startswith(SB3_PREFIX):
        return Path(name[len(SB3_PREFIX) :])
    target = POLICIES.get(name.partition("@")[0], name)
    spec = importlib.util.find_spec(target.partition(":")[0])
    return Path(spec.origin) if spec and spec.origin and spec.origin.endswith(".py") else None


def file_hash(path: Path) -> str:
    """SHA-256 of a file's bytes, as 64 hex digits."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def build_scorecard(
    suite: Suite, policy: PolicyEntry, runs: list[RunEntry], timing: Timing
) -> Scorecard:
    """The scorecard of ``policy`` (:func:`policy_identity`) with the figures ``runs`` of every run
    of ``suite`` (:func:`~nbv_gym.benchmark.suiterun.run_figures`)."""
    from nbv_gym.core.provenance import versions

    found = versions()
    return {
        "format": FORMAT,
        "protocol_version": PROTOCOL_VERSION,
        "suite": suite.identity(),
        "nbv_gym": {"version": found.pop("nbv-gym"), "git_commit": found.pop("git_commit")},
        "versions": found,
        "policy": policy,
        "optimality_target": TARGET_SCORE,
        "runs": runs,
        "aggregates": card_aggregates(runs, [part.description() for part in suite.parts]),
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "timing": timing,
    }


def join_scorecards(suite: Suite, cards: list[Scorecard]) -> Scorecard:
    """One scorecard of the parts of ``suite`` that ``cards`` hold between them — the cards of
    one policy, of one protocol version, each scored on some of the suite's parts
    (:meth:`~nbv_gym.benchmark.suites.Suite.only`): its runs in the suite's order, its
    aggregates computed again (the same figures a scoring of all those parts at once gives), its
    wall time the sum of theirs. :class:`ScorecardError` if they are of other policies or
    versions, or two hold one split."""
    first = cards[0]
    for card in cards:
        splits = [part["split"] for part in card["suite"]["parts"]]
        problem = (
            f"of protocol version {card['protocol_version']}, not {PROTOCOL_VERSION}"
            if card["protocol_version"] != PROTOCOL_VERSION
            else f"of another policy ({card['policy']['name']})"
            if card["policy"] != first["policy"]
            else f"of other parts than suite {suite.name}'s"
            if card["suite"] != suite.only(splits).identity()
            else ""
        )
        if problem:
            raise ScorecardError(f"cannot join a scorecard {problem} (splits {splits})")
    held = [part["split"] for card in cards for part in card["suite"]["parts"]]
    if len(held) != len(set(held)):
        raise ScorecardError(f"cannot join scorecards that both hold a split: {held}")
    joined = suite.only(held)
    runs = [
        run for split in joined.splits for c in cards for run in c["runs"] if run["split"] == split
    ]
    timing: Timing = {"wall_time_s": sum(c["timing"]["wall_time_s"] for c in cards),
              "workers": cards[-1]["timing"]["workers"]}  # fmt: skip
    return build_scorecard(joined, first["policy"], runs, timing)


def card_aggregates(
    runs: Sequence[RunEntry], parts: Sequence[PartDescription]
) -> dict[str, Aggregate]:
    """The ``aggregates`` of a scorecard: per part of the suite (its ``split`` and ``metric``,
    as in the card's ``suite.parts``), :func:`aggregate` of its runs. The one place they are
    computed: :mod:`nbv_gym.benchmark.validation` recomputes a loaded card's with it."""
    return {part["split"]: aggregate(runs, part["split"], part["metric"]) for part in parts}


def aggregate(runs: Sequence[RunEntry], split: str, metric: Metric) -> Aggregate:
    """Every aggregate of one split: ``metric`` summarised over all runs and per asset type
    (:func:`summary`), the plain means of :data:`MEAN_FIGURES` (and of
    :data:`TEAM_MEAN_FIGURES` for team runs), and, for runs that carry Q over
    effort (protocol version 2 on), ``effort``: Q at matched path, Q at the time budget (time
    task), the mean elapsed time and the mean curves (:func:`effort_aggregates`)."""
    mine = [run for run in runs if run["split"] == split]
    assets = list(dict.fromkeys(run["asset"] for run in mine))
    out: Aggregate = {
        "metric": metric,
        "all": summary(mine, metric, f"{split}/all"),
        "by_asset": {
            a: summary([r for r in mine if r["asset"] == a], metric, f"{split}/{a}") for a in assets
        },
        "means": {name: _mean([value_of(run, name) for run in mine]) for name in MEAN_FIGURES},
    }
    if mine and all("per_robot" in run for run in mine):
        out["means"] |= {name: _mean([value_of(run, name) for run in mine])
                         for name in TEAM_MEAN_FIGURES}  # fmt: skip
    if mine and all("q_path" in run for run in mine):
        out["effort"] = effort_aggregates(mine, split, metric)
    return out


def effort_aggregates(runs: Sequence[RunEntry], split: str, metric: Metric) -> Effort:
    """Over effort, for :func:`aggregate`: ``q_at_path`` (per matched path in metres, the
    :func:`summary` of Q there), ``q_at_budget`` (time task: the summary of the final Q, which
    is Q at the time budget; else None), ``elapsed_s`` (mean), and ``q_time``/``q_path``: the
    mean curve on the scorecard's grid with the 25th and 75th percentiles (``low``,
    ``high``)."""
    from nbv_gym.benchmark.curves import MATCHED_PATHS_M, PATH_GRID_M

    at_path: dict[str, Summary] = {}
    for distance in MATCHED_PATHS_M:
        index = PATH_GRID_M.index(distance)
        values = [run["q_path"][index] for run in runs]
        at_path[f"{distance:g}"] = summary(runs, "q_path", f"{split}/path{distance:g}", values)
    timed = metric == TIME_METRIC
    return {
        "q_at_path": at_path,
        "q_at_budget": summary(runs, "q", f"{split}/budget") if timed else None,
        "elapsed_s": _mean([run["elapsed_s"] for run in runs]),
        "q_time": _band([run["q_time"] for run in runs]),
        "q_path": _band([run["q_path"] for run in runs]),
    }


def _band(curves: Sequence[Sequence[Figure]]) -> Band:
    """Mean and 25th / 75th percentiles of equal-length ``curves``, point by point."""
    stack = np.asarray(curves, dtype=float)
    low, high = np.percentile(stack, [25, 75], axis=0)
    return {"mean": stack.mean(axis=0).tolist(), "low": low.tolist(), "high": high.tolist()}


def summary(
    runs: Sequence[RunEntry], metric: str, label: str, values: list[Any] | None = None
) -> Summary:
    """IQM, mean and optimality gap of ``metric`` over ``runs`` (or of ``values``, one per run,
    when given), each with its 95 % stratified bootstrap interval (strata: world × noise level;
    ``label`` seeds the bootstrap); ``n``: runs with a value."""
    from nbv_gym.reporting.inference import iqm, optimality_gap, stratified_interval

    given = values if values is not None else [value_of(run, metric) for run in runs]
    numbers = np.array([_number(value) for value in given], dtype=float)
    strata = [(run["world"], run["noise"]) for run in runs]
    seed = int.from_bytes(hashlib.sha256(label.encode()).digest()[:4], "big")
    rng = np.random.default_rng([BOOTSTRAP_SEED, seed])
    gap = partial(optimality_gap, target=TARGET_SCORE)
    iqm_, mean, gap_ = (
        stratified_interval(numbers, strata, statistic, rng) for statistic in (iqm, np.mean, gap)
    )  # drawn in this order: the intervals depend on it
    return {
        "n": int(np.isfinite(numbers).sum()),
        "iqm": iqm_.mean, "iqm_low": iqm_.low, "iqm_high": iqm_.high,
        "mean": mean.mean, "mean_low": mean.low, "mean_high": mean.high,
        "optimality_gap": gap_.mean, "optimality_gap_low": gap_.low,
        "optimality_gap_high": gap_.high,
    }  # fmt: skip


def write_scorecard(card: Scorecard, out: Path) -> tuple[Path, Path]:
    """Write ``scorecard.json`` (strict JSON) and ``scorecard.md`` into ``out``; their paths."""
    from nbv_gym.core.outputs import write_text

    json_path, md_path = out / "scorecard.json", out / "scorecard.md"
    write_text(json_path, dumps_strict(card))
    write_text(md_path, scorecard_markdown(card))
    return json_path, md_path


def dumps_strict(data: Any) -> str:
    """``data`` as JSON that every parser accepts: NaN and ±inf written as ``null``; arrays of
    numbers on one line (a scorecard holds two curves per run)."""
    return _NUMBER_ARRAY.sub(_one_line, dumps_json(data, indent=1)) + "\n"


#: A JSON array of numbers and nulls spread over lines by ``indent``.
_NUMBER_ARRAY = re.compile(
    r"\[\s*((?:-?[0-9][0-9.eE+-]*|null)(?:,\s*(?:-?[0-9][0-9.eE+-]*|null))*)\s*\]"
)


def _one_line(match: re.Match[str]) -> str:
    return "[" + re.sub(r",\s+", ", ", match.group(1)) + "]"


def load_scorecard(path: str | Path, recompute: bool = True) -> Scorecard:
    """The scorecard in ``path``, validated (:func:`~nbv_gym.benchmark.validation.validate_scorecard`:
    schema, runs and, if ``recompute``, the aggregates recomputed from the runs);
    :class:`ScorecardError` if it is not one or fails."""
    from nbv_gym.core.inputs import read_json

    path = Path(path)
    card = read_json(path, "Scorecard")
    if not isinstance(card, dict) or card.get("format") != FORMAT:
        raise ScorecardError(
            f'{path} is not an nbv-gym scorecard (no "format": "{FORMAT}"); give the '
            "scorecard.json that `nbv-gym score` wrote."
        )
    return validate_scorecard(card, path, card_aggregates if recompute else None)


def scorecard_markdown(card: Scorecard) -> str:
    """A short Markdown summary: identity, then per split its score (IQM and mean with 95 %
    intervals, optimality gap) overall and per asset type."""
    from nbv_gym.reporting.formatting import markdown_code, markdown_table

    policy, suite = card["policy"], card["suite"]
    oracle = " — **oracle** (reads privileged values; ranked apart)" if policy["oracle"] else ""
    lines = [
        f"# Scorecard: {markdown_code(policy['name'])}{oracle}",
        "",
        f"Suite `{suite['name']}` (hash `{suite['hash']}`, {len(card['runs'])} runs), protocol "
        f"version {card['protocol_version']}, nbv-gym {card['nbv_gym']['version']} "
        f"(commit `{card['nbv_gym']['git_commit'][:12]}`), policy code hash "
        f"`{str(policy['code_hash'])[:16]}` ({policy['hashed_file']}).",
        "",
        "IQM: interquartile mean; [95 % interval], stratified bootstrap over world × noise. "
        f"Optimality gap: mean shortfall below {card['optimality_target']:g}.",
        "",
    ]
    header = ["split", "task", "score", "runs", "IQM", "mean", "optimality gap", "discovered",
              "path (m)", "decision (ms)"]  # fmt: skip
    rows = [_split_row(part, card["aggregates"][part["split"]]) for part in suite["parts"]]
    lines += [markdown_table(header, rows), "", "## Score per asset type (IQM [95 % interval])", ""]
    assets = list(dict.fromkeys(a for agg in card["aggregates"].values() for a in agg["by_asset"]))
    asset_rows = [
        [
            split,
            *(
                interval_text(agg["by_asset"][a], "iqm") if a in agg["by_asset"] else "—"
                for a in assets
            ),
        ]
        for split, agg in card["aggregates"].items()
    ]
    lines += [markdown_table(["split", *assets], asset_rows), ""]
    lines += _effort_markdown(card)
    return "\n".join(lines)


def _effort_markdown(card: Scorecard) -> list[str]:
    """The effort section of :func:`scorecard_markdown`: per split, Q at the time budget and at
    matched path (IQM [95 % interval]) and the mean elapsed time ([] for cards without it)."""
    from nbv_gym.benchmark.curves import MATCHED_PATHS_M
    from nbv_gym.reporting.formatting import markdown_table

    rows = []
    for part in card["suite"]["parts"]:
        effort = card["aggregates"][part["split"]].get("effort")
        if not effort:
            continue
        at_budget, at_path = effort["q_at_budget"], effort["q_at_path"]
        rows.append([
            part["split"], part["task"],
            interval_text(at_budget, "iqm") if at_budget else "—",
            *(interval_text(at_path[f"{d:g}"], "iqm") for d in MATCHED_PATHS_M),
            number_text(effort["elapsed_s"], ".0f"),
        ])  # fmt: skip
    if not rows:
        return []
    header = ["split", "task", "Q at the time budget", *(f"Q at {d:g} m" for d in MATCHED_PATHS_M),
              "robot time (s)"]  # fmt: skip
    return [
        "## Q over effort (IQM [95 % interval])",
        "",
        "Time budget: travel and scans charged (path / speed + scans × scan time). Q at D m: Q "
        "after the last scan within D metres of path (the final Q if the run drove less).",
        "",
        markdown_table(header, rows),
        "",
    ]


def _split_row(part: PartDescription, agg: Aggregate) -> list[Any]:
    """One split's row of the scorecard's Markdown table."""
    from nbv_gym.core.protocol import TASK_CHARGES

    s, means = agg["all"], agg["means"]
    return [
        part["split"],
        f"{part['task']} ({TASK_CHARGES[part['task']]})",
        METRIC_LABELS[agg["metric"]],
        s["n"],
        interval_text(s, "iqm"),
        interval_text(s, "mean"),
        number_text(s["optimality_gap"]),
        number_text(means["discovered"], ".1%"),
        number_text(means["path_length_m"], ".1f"),
        decision_text(means["decision_time_s"]),
    ]


def interval_text(summary: Summary, name: str, digits: int = 4) -> str:
    """``value [low, high]`` of ``summary[name]``, or a dash when undefined."""
    value, low, high = (summary.get(k) for k in (name, f"{name}_low", f"{name}_high"))
    return estimate_text(value, low, high, f".{digits}f")


def decision_text(seconds: Any) -> str:
    """A mean decision time in milliseconds (two decimals), or a dash when undefined."""
    return number_text(None if undefined(seconds) else 1000 * seconds, ".2f")


def _number(value: Any) -> float:
    return math.nan if value is None else float(value)


def _mean(values: list[Any]) -> float:
    finite = [float(v) for v in values if not undefined(v)]
    return float(np.mean(finite)) if finite else math.nan
