"""The team leaderboard: scorecards of the team suite (N robots on one map and one clock) ranked
apart from single-robot ones (``nbv-gym leaderboard`` over team scorecards).

Rows: each scorecard's policy as a team and, for a scorecard holding the ``solo{N}-test`` parts,
the same policy as **one robot with N × the budget** — the same total robot time as a team of N
— whose scores stand in the team-of-N test column: each such column answers "is a team worth
it?". Ranked by the interquartile mean of the normalised area under the team's Q(t) over its
budget on the largest team's test split (one robot's: over N × the budget; both are the mean Q
over the same total robot time, so they compare); beside it the other team sizes and the shift
split, ``P(better)`` against the best row (the probability that a run of the row scores higher
on the same world and noise level, ties ½, with its stratified bootstrap interval), Q at the
budget, the time to the Q target, the overlap rate (Explore-Bench: the robots' coverages summed
over the team's, minus 1), the longest robot path, the summed path and the spread of the
robots' contributions. Figures: mean Q against elapsed time (to 3 × the budget, so one robot's
N × T runs are whole) and performance profiles per column.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from nbv_gym.benchmark.cardtypes import Scorecard
from nbv_gym.benchmark.ranking import Entry, baseline, improvement, is_team, ranked
from nbv_gym.benchmark.scorecard import interval_text
from nbv_gym.benchmark.suites import TEAM_SIZES, TEAM_SPLIT_LABELS, solo_split
from nbv_gym.core.errors import NbvGymError
from nbv_gym.reporting.formatting import (
    estimate_text,
    markdown_code,
    markdown_table,
    markdown_text,
    number_text,
    printable,
)

if TYPE_CHECKING:
    from nbv_gym.reporting.inference import Interval


class TeamBoardError(NbvGymError):
    """Team scorecards that cannot be put on a leaderboard as given; the message says why."""


def check_one_protocol(entries: list[Entry]) -> None:
    """:class:`TeamBoardError` for team scorecards given with single-robot ones."""
    team = [e.source for e in entries if is_team(e.card)]
    single = [e.source for e in entries if not is_team(e.card)]
    if team and single:
        raise TeamBoardError(
            f"Cannot rank team scorecards ({_sources(team)}: the team suite, N robots on one "
            f"map) with single-robot ones ({_sources(single)}); they rank apart: one "
            "leaderboard per kind."
        )


def _sources(sources: list[str]) -> str:
    unique = list(dict.fromkeys(sources))
    return unique[0] if len(unique) == 1 else f"{unique[0]} and {len(unique) - 1} more"


def one_robot_rows(entries: list[Entry]) -> list[Entry]:
    """Per entry holding ``solo{N}-test`` parts, the row of its policy as one robot with N × the
    budget: its card with those parts renamed ``team{N}-test`` (and nothing else), labelled
    ``<label>, one robot, N × T``."""
    rows = []
    for entry in entries:
        renamed = {solo_split(n): f"team{n}-test" for n in TEAM_SIZES}
        held = {s: t for s, t in renamed.items() if s in entry.card["aggregates"]}
        if held:
            card = _renamed(entry.card, held)
            rows.append(Entry(f"{entry.label}, one robot, N × T", card, entry.source))
    return rows


def _renamed(card: Scorecard, splits: dict[str, str]) -> Scorecard:
    """``card`` with only the parts, runs and aggregates of ``splits`` (old → new name), renamed."""
    parts = [{**p, "split": splits[p["split"]]} for p in card["suite"]["parts"]
             if p["split"] in splits]  # fmt: skip
    runs = [{**r, "split": splits[r["split"]]} for r in card["runs"] if r["split"] in splits]
    aggregates = {splits[s]: a for s, a in card["aggregates"].items() if s in splits}
    suite = {**card["suite"], "parts": parts}
    return cast(Scorecard, {**card, "suite": suite, "runs": runs, "aggregates": aggregates})


def write_team_board(entries: list[Entry], out: str | Path, verify: int) -> tuple[Path, Path, str]:
    """Write the team leaderboard (``leaderboard.md``, ``.html``, ``q-time.png``,
    ``profiles.png``) into ``out``: (Markdown path, HTML path, the ranking as plain text).
    ``verify``: must be 0 (a team run is not re-run yet)."""
    from nbv_gym.benchmark.figures import save_profiles, save_q_time
    from nbv_gym.core.outputs import claim_folder
    from nbv_gym.core.progress import say
    from nbv_gym.reporting.html import write_html

    if verify:
        raise TeamBoardError(
            "--verify re-runs single-robot runs only; team scorecards are checked against the "
            "schema and themselves (leave --verify out)."
        )
    split = entries[0].rank_split
    rows = [*entries, *(r for r in one_robot_rows(entries) if r.rank_split == split)]
    best = baseline(rows)
    say(f"ranking {len(rows)} rows of {len(entries)} team scorecards: P(better than "
        f"{best.label}) with its bootstrap interval per row…")  # fmt: skip
    better = {row.label: improvement(row, best) for row in rows if row is not best}
    out = claim_folder(Path(out), "leaderboard")
    columns = [s for s in TEAM_SPLIT_LABELS if any(row.has(s) for row in rows)]
    save_q_time(rows, out / "q-time.png")
    save_profiles(rows, out / "profiles.png", {s: TEAM_SPLIT_LABELS[s] for s in columns})
    path = out / "leaderboard.md"
    path.write_text(team_markdown(rows, better, columns), encoding="utf-8")
    return path, write_html(path), team_summary(rows, better)


def team_markdown(rows: list[Entry], better: dict[str, Interval], columns: list[str]) -> str:
    """The team leaderboard as Markdown (module docstring)."""
    players, _ = ranked(rows)  # a team runs agent policies only: no oracle
    best, suite = baseline(rows), rows[0].card["suite"]
    split = best.rank_split
    header = ["rank", "policy", *(TEAM_SPLIT_LABELS[s].column for s in columns),
              f"P(better than {markdown_text(best.label)}, {split})", "Q at the budget",
              "time to Q target (s)", "overlap", "longest path (m)", "path, all robots (m)",
              "contribution spread"]  # fmt: skip
    table = [_row(str(i + 1), row, better, columns) for i, row in enumerate(players)]
    target = next((p.get("q_target") for p in suite["parts"] if "q_target" in p), None)
    return "\n".join([
        "# Team leaderboard",
        "",
        f"Suite {markdown_code(suite['name'])} (hash {markdown_code(suite['hash'])}), protocol "
        f"version {rows[0].card['protocol_version']}: {markdown_text(suite['description'])}.",
        "",
        _legend(split, number_text(target, "g")),
        "",
        markdown_table(header, table),
        "",
        "## Q against elapsed time",
        "",
        f"Mean Q against the team's clock on {split}, with the interquartile band over runs "
        "(one robot's N × T rows run on to N × the budget).",
        "",
        "![Q against elapsed time](q-time.png)",
        "",
        "## Performance profiles",
        "",
        "Fraction of runs whose score exceeds τ per row, with 95 % stratified-bootstrap bands.",
        "",
        "![performance profiles](profiles.png)",
        "",
    ])  # fmt: skip


def _legend(split: str, target: str) -> str:
    return (
        f"Ranked by the interquartile mean (IQM) of the area under the team's Q(t) over its "
        f"budget on {split} (the mean Q the team held, travel and scans charged per robot). "
        "*One robot, N × T*: the same policy as a single robot with N × the budget, the same "
        "total robot time as a team of N; its score (the mean Q over N × T) stands in the team "
        "of N's test column, so each column asks whether a team is worth its robots. "
        "[brackets]: 95 % intervals, stratified bootstrap (runs resampled within each world × "
        "noise level). P(better): the probability that a run of the row scores higher than a run "
        "of the best row on the same world and noise level (ties ½). Beside the score, on the "
        f"ranking split: Q at the budget (IQM), the mean team time to Q ≥ {target} (over the runs "
        "that reached it), the mean overlap rate (Explore-Bench: the robots' coverages summed "
        "over the team's, minus 1; 0 = no goal cell changed by two robots), the mean longest "
        "robot path and summed path, and the spread of the robots' shares of the change of Q "
        "(0 = an even split)."
    )


def _row(rank: str, row: Entry, better: dict[str, Interval], columns: list[str]) -> list[Any]:
    found = row.aggregates()
    means = found["means"] if found else {}
    effort = row.effort()
    at_budget = effort["q_at_budget"] if effort else None
    return [
        rank,
        markdown_code(row.label),
        *(interval_text(row.card["aggregates"][s]["all"], "iqm") if row.has(s) else "—"
          for s in columns),
        _poi(better.get(row.label)),
        interval_text(at_budget, "iqm") if at_budget else "—",
        number_text(means.get("time_to_q_s"), ".0f"),
        number_text(means.get("overlap_rate"), ".2f"),
        number_text(means.get("longest_path_m"), ".0f"),
        number_text(means.get("path_length_m"), ".0f"),
        number_text(means.get("contribution_spread"), ".2f"),
    ]  # fmt: skip


def _poi(poi: Interval | None) -> str:
    return "(best)" if poi is None else estimate_text(poi.mean, poi.low, poi.high, ".2f")


def team_summary(rows: list[Entry], better: dict[str, Interval]) -> str:
    """The team ranking as a plain-text table: rank, policy, the ranking score, ``P(better)``,
    the overlap rate and the longest robot path."""
    players, _ = ranked(rows)
    split = rows[0].rank_split
    table = [["rank", "policy", f"{split}: IQM area under Q(t)", "P(better)", "overlap",
              "longest path (m)"]]  # fmt: skip
    for i, row in enumerate(players):
        found = row.aggregates()
        means = found["means"] if found else {}
        table.append([str(i + 1), printable(row.label),
                      interval_text(found["all"], "iqm") if found else "—",
                      _poi(better.get(row.label)), number_text(means.get("overlap_rate"), ".2f"),
                      number_text(means.get("longest_path_m"), ".0f")])  # fmt: skip
    widths = [max(len(r[k]) for r in table) for k in range(len(table[0]))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in table]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)
