"""The leaderboard: scorecards of one suite and protocol version ranked in one table, with the
probability of improvement over the best reference, the Pareto front of Q and path, Q against
elapsed time and performance profiles (``nbv-gym leaderboard``).

Ranking: by the interquartile mean of the area under Q(t) over the time budget on the test split
of the time task (equal robot time: travel and scans charged; the held-out worlds); oracles
(policies that read privileged values) are ranked apart, below. Beside it: the same on the
benchmark worlds, Q after the budget of scans (equal scans, travel free), Q_paper at 70 %
discovered under the paper's protocol, and ``P(X > best)``: the probability that a run of the
entry scores higher than a run of the best reference on the same test world and noise level (ties ½),
averaged over those tasks, with its 95 % interval under the stratified bootstrap (the runs of
both redrawn within each task). The effort table gives, on the time task's test split, Q at the
budget, Q at matched path (25–200 m), the mean path and whether another policy dominates the
entry on (mean Q at the budget, mean path): as good a map for no longer a path, one of them
strictly. Figures: mean Q against elapsed time per policy with its interquartile band, and
performance profiles (Agarwal et al., *Deep RL at the edge of the statistical precipice*,
NeurIPS 2021): per policy the fraction of runs scoring above τ, with 95 % stratified-bootstrap
bands.

Beside the headline, the shift split (time task on worlds of recipes outside every training
distribution) has its own column and its own ``P(X > best)`` against the best reference that
holds it. Scorecards merge when they share the suite's name and protocol version and every split
two of them hold has one part hash: a reference scored before a part joined the suite stands for
its other parts, and the board says that the new part is pending for it.

References scored under another protocol version or suite are left out, and the board says
that references for this version are pending.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from nbv_gym.benchmark.cardtypes import Scorecard, value_of
from nbv_gym.benchmark.figures import save_profiles, save_q_time
from nbv_gym.benchmark.ranking import (
    RANK_SPLITS,
    Entry,
    baseline,
    improvement,
    is_team,
    pareto_dominated,
    ranked,
)
from nbv_gym.benchmark.scorecard import decision_text, interval_text, load_scorecard
from nbv_gym.benchmark.suites import SHIFT_SPLIT, SPLIT_LABELS
from nbv_gym.benchmark.teamboard import check_one_protocol, write_team_board
from nbv_gym.core.errors import NbvGymError
from nbv_gym.reporting.formatting import (
    estimate_text,
    markdown_code,
    markdown_text,
    number_text,
    printable,
)
from nbv_gym.sensor.presets import DEFAULT_LIDAR

if TYPE_CHECKING:
    from nbv_gym.reporting.inference import Interval


class LeaderboardError(NbvGymError):
    """Scorecards that cannot be put on one leaderboard; the message says which and why."""


def gather(paths: list[str | Path], references: bool, suite: str | None = None) -> list[Entry]:
    """The entries of the scorecard files (or folders holding ``scorecard.json``) ``paths``,
    plus, if ``references``, the shipped references of their suite (of ``suite``, by default
    the standard suite, when no path is given) that belong to this protocol version (stale ones are left out:
    :func:`~nbv_gym.benchmark.references.pending_note`); :class:`LeaderboardError` if there are
    none, if that suite has no references, or if the scorecards belong to different suites or
    protocol versions."""
    from nbv_gym.benchmark.references import (
        REFERENCE_SUITE,
        current_references,
        load_references,
        references_note,
    )

    given = [(path, _given_card(path)) for path in _scorecard_paths(paths)]
    entries: list[Entry] = []
    pending = ""
    if suite is not None and (given or not references):
        raise LeaderboardError(
            f"--suite {suite} names whose references to rank without a scorecard (with "
            "--references); a scorecard's references are those of its own suite."
        )
    if references:
        suite = given[0][1]["suite"]["name"] if given else suite or REFERENCE_SUITE.name
        if not load_references(suite):
            raise LeaderboardError(_no_references(suite))
        current, _ = current_references(suite)
        entries += [Entry(c["policy"]["name"], c, "references") for c in current]
        pending = references_note(suite)
    for path, card in given:
        label = card["policy"]["name"]
        if any(e.label == label for e in entries):
            label = f"{label} ({path})"
        entries.append(Entry(label, card, str(path)))
    if not entries:
        raise LeaderboardError(
            f"No scorecard to rank: {pending or ''}{' ' if pending else ''}Give scorecard files "
            "(from `nbv-gym score`) and/or --references."
        )
    check_comparable(entries)
    return entries


def _scorecard_paths(paths: list[str | Path]) -> list[Path]:
    """The scorecard files of ``paths`` (a folder stands for its ``scorecard.json``), each once:
    :class:`LeaderboardError` for a file given twice."""
    seen: dict[Path, Path] = {}
    for path in map(Path, paths):
        path = path / "scorecard.json" if path.is_dir() else path
        if path.resolve() in seen:
            raise LeaderboardError(
                f"{path} is given twice (also as {seen[path.resolve()]}); each scorecard "
                "counts once."
            )
        seen[path.resolve()] = path
    return list(seen.values())


def _given_card(path: Path) -> Scorecard:
    """The scorecard at ``path`` (validated on load); :class:`LeaderboardError` if it lacks the
    split that ranks the leaderboard."""
    card = load_scorecard(path)
    _check_shipped_suite(card, path)
    if not any(split in card["aggregates"] for split in RANK_SPLITS):
        raise LeaderboardError(
            f"{path} has no time-task split ({' or '.join(RANK_SPLITS[:2])}), nor a team one "
            f"({' or '.join(RANK_SPLITS[2:])}), which ranks the leaderboard; score the policy on a suite with one (`nbv-gym score POLICY --suite "
            "standard`)."
        )
    return card


def _check_shipped_suite(card: Scorecard, path: Path) -> None:
    """:class:`LeaderboardError` unless a scorecard that names a shipped suite records that
    suite as this nbv-gym defines it (its hash, seed and parts: an edited budget or a dropped
    repeat with the hash kept, or a card of another nbv-gym version, would rank otherwise)."""
    from nbv_gym.benchmark.suites import shipped_identity

    recorded = card["suite"]
    expected = shipped_identity(recorded)
    if expected is None or recorded == expected:
        return
    field = next(k for k in expected if recorded.get(k) != value_of(expected, k))
    raise LeaderboardError(
        f"{path}: its suite {recorded['name']!r} differs from this nbv-gym's (suite.{field}); "
        f"score the policy again with this nbv-gym (`nbv-gym score POLICY --suite "
        f"{recorded['name']}`)."
    )


def _no_references(suite: str) -> str:
    from nbv_gym.benchmark.references import reference_suites

    have = ", ".join(reference_suites()) or "none"
    return (
        f"No reference scorecards of the {suite!r} suite ship with this nbv-gym (suites with "
        f"references: {have}). Rank without --references, or score on a suite that has them "
        f"(`nbv-gym score POLICY --suite standard`)."
    )


def check_comparable(entries: list[Entry]) -> None:
    """Raise :class:`LeaderboardError` naming each source's suite and protocol version unless all
    ``entries`` share one suite name and protocol version, every split two of them hold is one
    part (its hash), and all rank by one split."""
    check_one_protocol(entries)
    identities: dict[tuple[str, str, int, str], list[str]] = {}
    hashes: dict[str, set[str]] = {}
    for entry in entries:
        suite = entry.card["suite"]
        lidars = sorted({part.get("lidar", DEFAULT_LIDAR) for part in suite["parts"]})
        identity = (suite["name"], suite["hash"], entry.card["protocol_version"], ", ".join(lidars))
        identities.setdefault(identity, []).append(entry.source)
        for part in suite["parts"]:
            hashes.setdefault(part["split"], set()).add(part["hash"])
    names = {(name, version) for name, _, version, _ in identities}
    if len(names) == 1 and all(len(found) == 1 for found in hashes.values()):
        _check_same_parts(entries)
        _check_rank_split(entries)
        return
    described = "; ".join(
        f"{_sources(sources)}: suite {name} (hash {digest}, lidar {lidar}), protocol version "
        f"{version}"
        for (name, digest, version, lidar), sources in identities.items()
    )
    raise LeaderboardError(
        f"Cannot merge scorecards of different suites or protocol versions — {described}. Score "
        "every policy on the same suite with the same nbv-gym (`nbv-gym score POLICY --suite "
        "standard`; --references adds the references of the scorecards' suite)."
    )


def _check_same_parts(entries: list[Entry]) -> None:
    """Scorecards of one suite hash record one suite: the hash stands for the suite's worlds and
    parts, so two cards that share it but list other parts (worlds renamed, a part dropped) are
    refused — one of them was edited (an own-world suite's hash cannot be recomputed from its
    card: it hashes the spec files' contents)."""
    firsts: dict[str, Entry] = {}
    for entry in entries:
        first = firsts.setdefault(entry.card["suite"]["hash"], entry)
        for key in ("seed", "parts"):
            if entry.card["suite"][key] != first.card["suite"][key]:
                suite = first.card["suite"]
                raise LeaderboardError(
                    f"{first.source} and {entry.source} record suite {suite['name']} with one "
                    f"hash ({suite['hash']}) but different suite.{key}; one hash stands for one "
                    "suite, so one of them was edited. Score both policies again on the same "
                    "suite."
                )


def _check_rank_split(entries: list[Entry]) -> None:
    """:class:`LeaderboardError` unless every entry ranks by the same split."""
    splits: dict[str, list[str]] = {}
    for entry in entries:
        splits.setdefault(entry.rank_split, []).append(entry.source)
    if len(splits) > 1:
        described = "; ".join(f"{_sources(s)}: {split}" for split, s in splits.items())
        raise LeaderboardError(
            f"Cannot rank scorecards by different splits — {described}; score every policy on "
            "the whole suite (`nbv-gym score POLICY --suite standard`)."
        )


def _sources(sources: list[str]) -> str:
    unique = list(dict.fromkeys(sources))
    return unique[0] if len(unique) == 1 else f"{unique[0]} and {len(unique) - 1} more"


@dataclass(frozen=True)
class Leaderboard:
    """What :func:`build_leaderboard` wrote (``markdown``, ``html``) and the ranking as plain
    text for a terminal (``summary``)."""

    markdown: Path
    html: Path
    summary: str


def build_leaderboard(
    paths: list[str | Path],
    references: bool,
    out: str | Path,
    suite: str | None = None,
    verify: int = 0,
    verify_seed: int = 0,
) -> Leaderboard:
    """Write ``leaderboard.md``, ``leaderboard.html``, Q against elapsed time
    (``q-time.png``/``.svg``) and the performance profiles (``profiles.png``/``.svg``) into
    ``out``; with ``verify`` > 0, first re-run that many runs of each given scorecard, chosen
    with ``verify_seed`` (:func:`~nbv_gym.benchmark.rerun.verify_entries`), and refuse a card
    whose runs do not reproduce."""
    from nbv_gym.benchmark.rerun import verify_entries
    from nbv_gym.core.outputs import check_owner, claim_folder
    from nbv_gym.core.progress import say
    from nbv_gym.reporting.html import write_html

    check_owner(out, "leaderboard")  # another command's folder fails before any work
    entries = gather(paths, references, suite)
    if is_team(entries[0].card):
        return Leaderboard(*write_team_board(entries, out, verify))
    verified = verify_entries(entries, verify, verify_seed, say) if verify else []
    pending = _pending_references(entries) if references else ""
    say(f"ranking {len(entries)} scorecards: P(better than {baseline(entries).label}) with its "
        "bootstrap interval per entry…")  # fmt: skip
    improvements = improvements_over_baseline(entries)
    shift = improvements_over_baseline(entries, SHIFT_SPLIT) if shift_shown(entries) else None
    out = claim_folder(Path(out), "leaderboard")
    say("drawing Q against the robot's time and the performance profiles…")
    save_q_time(entries, out / "q-time.png")
    save_profiles(entries, out / "profiles.png")
    text = leaderboard_markdown(entries, improvements, pending, shift, verified)
    (path := out / "leaderboard.md").write_text(text, encoding="utf-8")
    notes = [pending, *(f"re-run: {note}" for note in verified)]
    summary = "\n".join([leaderboard_summary(entries, improvements, shift), *filter(None, notes)])
    return Leaderboard(path, write_html(path), summary)


def improvements_over_baseline(
    entries: list[Entry], split: str | None = None
) -> dict[str, Interval]:
    """``P(entry > baseline)`` with its interval (:func:`improvement`) on ``split`` (default:
    the ranking split) per entry label that holds it; the baseline itself is left out."""
    best = baseline(entries, split)
    return {
        e.label: improvement(e, best, split=split)
        for e in entries
        if e is not best and (split is None or e.has(split))
    }


def shift_shown(entries: list[Entry]) -> bool:
    """Whether the board shows the shift split's ``P(better)``: some entry's suite has it and
    some entry holds it."""
    return any(SHIFT_SPLIT in e.suite_splits for e in entries) and any(
        e.has(SHIFT_SPLIT) for e in entries
    )


def leaderboard_summary(
    entries: list[Entry],
    improvements: dict[str, Interval] | None = None,
    shift: dict[str, Interval] | None = None,
) -> str:
    """The ranking as a plain-text table: rank, policy, the ranking score with its interval,
    ``P(better than baseline)``, and the shift split's score and ``P(better)`` when shown
    (``shift``: :func:`improvements_over_baseline` on it, computed when not given); oracles
    last; beside references, ``*`` marks the scorecards given on the command line."""
    players, oracles = ranked(entries)
    best = baseline(entries)
    improvements = improvements_over_baseline(entries) if improvements is None else improvements
    shift = _shift_improvements(entries, shift)
    mixed = any(e.reference for e in entries) and not all(e.reference for e in entries)
    header = [
        "rank",
        "policy",
        SPLIT_LABELS[best.rank_split].column,
        f"P(better than {best.label}, equal time)",
    ]
    if shift is not None:
        header += [SPLIT_LABELS[SHIFT_SPLIT].column, _shift_title(entries, plain=True)]
    rows = [header]
    for rank, entry in [
        *((str(i + 1), e) for i, e in enumerate(players)),
        *(("oracle", e) for e in oracles),
    ]:
        test = entry.aggregates()
        rows.append([
            rank,
            printable(entry.label) + (" *" if mixed and not entry.reference else ""),
            interval_text(test["all"], "iqm") if test else "—",
            _poi_text(improvements.get(entry.label)),
            *(_shift_cells(entry, shift) if shift is not None else ()),
        ])  # fmt: skip
    widths = [max(len(row[i]) for row in rows) for i in range(len(header))]
    lines = [
        "  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip()
        for row in rows
    ]
    lines.insert(1, "  ".join("-" * w for w in widths))
    if mixed:
        lines.append("* given on the command line; the others are the shipped references")
    return "\n".join(lines)


def leaderboard_markdown(
    entries: list[Entry],
    improvements: dict[str, Interval] | None = None,
    pending: str = "",
    shift: dict[str, Interval] | None = None,
    verified: list[str] | None = None,
) -> str:
    """The leaderboard as Markdown: the ranked scores, the effort behind them, the oracles apart,
    the figures; ``improvements`` (:func:`improvements_over_baseline`) and ``shift`` (the same
    on the shift split, when shown) computed when not given; ``pending``: a note that
    references (or some of their splits) are pending, shown in bold above the tables;
    ``verified``: per given scorecard, which of its runs were re-run here
    (:func:`~nbv_gym.benchmark.rerun.verify_entries`)."""
    players, oracles = ranked(entries)
    best = baseline(entries)
    improvements = improvements_over_baseline(entries) if improvements is None else improvements
    shift = _shift_improvements(entries, shift)
    # the suite as the scorecard with the most parts records it (a reference may lack a part)
    suite = max((e.card["suite"] for e in entries), key=lambda recorded: len(recorded["parts"]))
    version = entries[0].card["protocol_version"]
    lines = [
        "# Leaderboard",
        "",
        f"Suite {markdown_code(suite['name'])} (hash {markdown_code(suite['hash'])}), protocol "
        f"version {version}: {markdown_text(suite['description'])}.",
        "",
        *([f"**{pending}**", ""] if pending else []),
        _legend(best),
        "",
        *_checked(entries, verified or []),
        _tables(players, best, (improvements, shift), rank=True),
    ]
    lines += _pending(entries)
    if oracles:
        lines += [
            "",
            "## Oracles (ranked apart)",
            "",
            "These policies declare that they read privileged values (the ground truth, the true "
            "pose or the world's name), which no robot has: they bound what is "
            "reachable and are not ranked with the others.",
            "",
            _tables(oracles, best, (improvements, shift), rank=False),
        ]
    lines += [
        "",
        "## Q against the robot's time",
        "",
        "Mean Q against elapsed time (path / speed + scans × scan time) on the time task's test "
        "split, with the interquartile band over runs; oracles dashed.",
        "",
        "![Q against elapsed time](q-time.png)",
        "",
        "## Performance profiles",
        "",
        "Fraction of runs whose score exceeds τ, per policy, with 95 % stratified-bootstrap "
        "bands (a curve above another is better at every threshold); oracles dashed.",
        "",
        "![performance profiles](profiles.png)",
        "",
    ]
    return "\n".join(lines)


def _pending(entries: list[Entry]) -> list[str]:
    """Lines naming the shipped policies without a reference scorecard, when references are
    shown."""
    from nbv_gym.benchmark.references import pending

    missing = pending(entries[0].card["suite"]["name"])
    if not any(e.reference for e in entries) or not missing:
        return []
    named = "; ".join(f"`{name}` ({why})" for name, why in missing.items())
    return ["", f"Shipped policies without a reference scorecard yet: {named}."]


def _pending_references(entries: list[Entry]) -> str:
    """The note that references of the entries' suite for this protocol version, or some of
    their splits, are pending ("" when all are current and whole)."""
    from nbv_gym.benchmark.references import references_note

    return references_note(entries[0].card["suite"]["name"])


def _tables(
    entries: list[Entry],
    best: Entry,
    improvements: tuple[dict[str, Interval], dict[str, Interval] | None],
    rank: bool,
) -> str:
    """The scores table and the effort table of ``entries``; ``improvements``: (on the ranking
    split, on the shift split or None when not shown)."""
    from nbv_gym.benchmark.curves import MATCHED_PATHS_M
    from nbv_gym.reporting.formatting import markdown_table

    ranking, shift = improvements
    ranks = [str(i + 1) if rank else "oracle" for i in range(len(entries))]
    scores = [
        "rank",
        "policy",
        *(labels.column for labels in SPLIT_LABELS.values()),
        f"P(better than {markdown_text(best.label)}, equal time)",
        *([_shift_title(entries)] if shift is not None else []),
    ]
    effort = ["rank", "policy", "Q at the budget", *(f"Q at {d:g} m" for d in MATCHED_PATHS_M),
              "path (m)", "time (s)", "Pareto (Q, path)", "decision (ms/step)"]  # fmt: skip
    dominated = pareto_dominated(entries)
    return "\n\n".join(
        [
            markdown_table(
                scores,
                [_score_row(r, e, ranking, shift) for r, e in zip(ranks, entries, strict=True)],
            ),
            "Effort behind the score (time task, test split; IQM [95 % interval] and means per "
            "run; Pareto: dominated by a policy with as high an IQM of Q at the budget for as short "
            "a mean path to the metre, one strictly):",
            markdown_table(
                effort,
                [_effort_row(r, e, dominated) for r, e in zip(ranks, entries, strict=True)],
            ),
        ]
    )


def _checked(entries: list[Entry], verified: list[str]) -> list[str]:
    """Lines saying what was checked of the scorecards given on the command line (none when
    there are none): always their schema, runs, aggregates and each run against itself; re-runs
    only with ``--verify``."""
    if all(e.reference for e in entries):
        return []
    checked = (
        "Each scorecard given on the command line was checked against the schema, its suite and "
        "itself (every aggregate from its runs; each run's clock, curves and area under Q(t))"
    )
    if not verified:
        return [f"{checked}; its runs were not re-run here (`--verify N` re-runs N of them).", ""]
    notes = "; ".join(markdown_text(note) for note in verified)
    return [f"{checked}, and sampled runs were re-run here: {notes}.", ""]


def _legend(best: Entry) -> str:
    whom = "the best reference" if best.reference else "the best entry (no reference given)"
    return (
        "Ranked by the interquartile mean (IQM) of the area under Q(t) over the time budget "
        "(the mean Q the robot held, with travel and scans charged by the effort model) on the "
        "test split of the time task, the worlds no policy was tuned or trained on. The budget "
        "task's columns give Q after a fixed number of scans with travel free (the robot "
        "teleports), the paper's protocol Q_paper at 70 % discovered; neither charges travel. "
        "[brackets]: 95 % intervals, stratified "
        "bootstrap (runs resampled within each world × noise level). "
        f"P(better than {markdown_text(best.label)}, equal time): the probability that a run of the policy has a higher area under Q(t) over the time budget than a run of "
        f"{whom} on the same test world and noise level (ties ½); 0.5 = no difference. "
        "The shift split's column and its P(better): the same on worlds of recipes outside every "
        "training distribution (denser, sparser, tighter clusters, larger forests), against the "
        "best reference that holds it; *pending*: the split joined the suite after that "
        "scorecard was made. "
        "Decision time: the policy's `act`, mean per step. **Bold**: scorecards given on the "
        "command line; the others are the shipped references."
    )


def _name(entry: Entry) -> str:
    code = markdown_code(entry.label)
    return code if entry.reference else f"**{code}**"


def _score_row(
    rank: str, entry: Entry, improvements: dict[str, Interval], shift: dict[str, Interval] | None
) -> list[Any]:
    """One row of the scores table: the score of every split (``pending`` for a split of its
    suite the scorecard lacks), ``P(better than baseline)`` and, when shown, on the shift
    split."""
    return [
        rank,
        _name(entry),
        *(_split_cell(entry, split) for split in SPLIT_LABELS),
        _poi_text(improvements.get(entry.label)),
        *([_shift_cells(entry, shift)[1]] if shift is not None else []),
    ]


def _split_cell(entry: Entry, split: str) -> str:
    """The IQM [interval] of ``split``; ``pending`` if the entry's suite has it and the
    scorecard does not; ``—`` otherwise."""
    if entry.has(split):
        return interval_text(entry.card["aggregates"][split]["all"], "iqm")
    return "pending" if split in entry.suite_splits else "—"


def _poi_text(poi: Interval | None) -> str:
    """``mean [low, high]`` of a ``P(better)``, or ``(baseline)`` for None."""
    return "(baseline)" if poi is None else estimate_text(poi.mean, poi.low, poi.high, ".2f")


def _shift_improvements(
    entries: list[Entry], shift: dict[str, Interval] | None
) -> dict[str, Interval] | None:
    """``P(better)`` on the shift split per entry (``shift`` if given), or None when the board
    does not show it (:func:`shift_shown`)."""
    if not shift_shown(entries):
        return None
    return improvements_over_baseline(entries, SHIFT_SPLIT) if shift is None else shift


def _shift_title(entries: list[Entry], plain: bool = False) -> str:
    """The shift split's ``P(better)`` column title, naming its baseline."""
    best = baseline(entries, SHIFT_SPLIT).label
    return f"P(better than {best if plain else markdown_text(best)}, shift)"


def _shift_cells(entry: Entry, shift: dict[str, Interval]) -> tuple[str, str]:
    """(score, ``P(better)``) of ``entry`` on the shift split: ``pending`` both when its
    scorecard lacks the split its suite has."""
    if not entry.has(SHIFT_SPLIT):
        return (_split_cell(entry, SHIFT_SPLIT),) * 2
    return _split_cell(entry, SHIFT_SPLIT), _poi_text(shift.get(entry.label))


def _effort_row(rank: str, entry: Entry, dominated: dict[str, str]) -> list[Any]:
    """One row of the effort table."""
    from nbv_gym.benchmark.curves import MATCHED_PATHS_M

    test, effort = entry.aggregates(), entry.effort()
    means = test["means"] if test else {}
    at_budget = effort["q_at_budget"] if effort else None
    at_path = effort["q_at_path"] if effort else {}
    return [
        rank,
        _name(entry),
        interval_text(at_budget, "iqm") if at_budget else "—",
        *(
            interval_text(at_path[f"{d:g}"], "iqm") if f"{d:g}" in at_path else "—"
            for d in MATCHED_PATHS_M
        ),
        number_text(means.get("path_length_m"), ".0f"),
        number_text(effort["elapsed_s"] if effort else None, ".0f"),
        f"dominated by {markdown_code(dominated[entry.label])}"
        if entry.label in dominated
        else "front",
        decision_text(means.get("decision_time_s")),
    ]
