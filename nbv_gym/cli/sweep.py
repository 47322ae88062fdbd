"""``nbv-gym sweep`` and ``nbv-gym report``: plain typer-annotated functions the CLI registers."""

from __future__ import annotations

import contextlib
import os
import signal
import warnings
from pathlib import Path
from typing import Annotated

import typer

from nbv_gym.cli.options import LidarOption
from nbv_gym.cli.params import COUNT, POSITIVE_COUNT
from nbv_gym.core.jsonfiles import dumps_json


def sweep(
    config: Annotated[
        str,
        typer.Argument(
            help="A shipped sweep config (quick, paper, rl-eval, nbv-visibility; see nbv-gym "
            "configs list) or the path of a sweep config file (TOML)."
        ),
    ],
    out: Annotated[
        Path | None, typer.Option(help="Results folder [default: results/<config name>].")
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(
            help="Local worker processes, or LocalCluster workers, ≥ 1 [default: all cores].",
            parser=POSITIVE_COUNT,
        ),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option(
            help="Run on the Dask cluster at this address (tcp://host:8786; tls://host:8786 with "
            "Dask's TLS settings, see docs/security.md), or 'local' for a new "
            "Dask LocalCluster. Needs nbv-gym[dist]."
        ),
    ] = None,
    retries: Annotated[
        int | None,
        typer.Option(help="Retries of a failed run [default: the config's].", parser=COUNT),
    ] = None,
    lidar: LidarOption = None,
    report: Annotated[bool, typer.Option(help="Build the report at the end.")] = True,
    progress: Annotated[bool, typer.Option(help="Show a progress bar on stderr.")] = True,
    as_json: Annotated[
        bool,
        typer.Option(
            "--json",
            help="Print the summary as one JSON object on stdout (the rest goes to stderr).",
        ),
    ] = False,
) -> None:
    """Run a sweep of episodes (worlds × noise × policies × repeats), resumably, in parallel.

    Each finished run is written atomically to OUT/runs/; rerunning the same command resumes and
    never redoes a finished run. A run that raises, whose worker dies, or that runs longer than
    the config's run_timeout_s (default 1800 s) is recorded in OUT/failures/ with its traceback
    and retried up to the retry limit; the other runs go on. An unreadable run file is moved to
    OUT/corrupt/ (and named) and its run done again. The config must name worlds and policies;
    the defaults used for the other keys are printed.
    At the end OUT/runs.csv (one row per run), OUT/steps.csv (one row per step) and
    OUT/cuboids.parquet (per-cuboid statistics and quality) are rebuilt, and the report is
    written to OUT/report/report.md. Policies given as module:Class are imported from the
    config file's folder or the current folder: a config naming module:Class or sb3:MODEL.zip
    policies runs code from those files, so run only configs you trust.

    Examples:

        nbv-gym sweep quick --out results/quick

        nbv-gym sweep paper --out results/paper --workers 2

        nbv-gym sweep paper --out results/paper --scheduler tcp://HOST:8786

        nbv-gym sweep my-sweep.toml --scheduler local --workers 2

        nbv-gym sweep quick --json > quick.json

        nbv-gym sweep quick --lidar os1-64 --out results/quick-os1-64
    """
    from nbv_gym.configs import config_file
    from nbv_gym.core.outputs import check_owner
    from nbv_gym.sweep.backends import reach_scheduler
    from nbv_gym.sweep.config import read_sweep_config, with_lidar, with_overrides
    from nbv_gym.sweep.runner import run_sweep, summary_rows

    config_path = config_file(config, "sweep")
    sweep_config, filled = read_sweep_config(config_path)
    sweep_config = with_lidar(with_overrides(sweep_config, retries=retries), lidar)
    if filled:
        defaults = ", ".join(f"{key} = {value!r}" for key, value in filled.items())
        typer.echo(
            f"{config_path} leaves out some keys; their defaults are used: {defaults}", err=True
        )
    out = out or Path("results") / sweep_config.name
    check_owner(out, "sweep")
    reach_scheduler(scheduler)  # a bad or silent scheduler fails before any folder
    python_path = (str(config_path.resolve().parent), os.getcwd())
    with resumable(out / "runs"):
        summary = run_sweep(sweep_config, out, workers, scheduler, python_path, progress)
    _echo_set_aside(summary.set_aside)
    rows = summary_rows(out, sweep_config.policies)
    _echo_summary(summary, rows, as_json)
    built = _build_report(out) if report else None
    if built is not None:
        typer.echo(f"report: {built}", err=as_json)
    if as_json:
        typer.echo(dumps_json(_json_summary(out, summary, rows, built)))
    if summary.failed:
        typer.secho(
            f"{len(summary.failed)} run(s) failed after retries (see {out}/failures/); rerun "
            "the same command to retry them.",
            err=True,
            fg="red",
        )
        raise SystemExit(1)


def report(
    results: Annotated[Path, typer.Argument(help="Results folder of a sweep.")],
    out: Annotated[
        Path | None, typer.Option(help="Folder for the report [default: RESULTS/report].")
    ] = None,
    pdf: Annotated[
        bool, typer.Option(help='Also write report.pdf (needs: pip install "nbv-gym[pdf]").')
    ] = False,
) -> None:
    """Build the report of a sweep: figures (PNG and SVG), tables (CSV), report.md, report.html
    and, with --pdf, report.pdf (laid out without a browser).

    Reproduces the NBV paper's Fig. 2 (Q against discovered fraction per policy and asset type,
    mean with min-max band), Fig. 1 (mean cov and L1 against each viewpoint statistic per asset
    type) and Table II (share of one-sided Mann-Whitney tests with p < 0.05, on the
    random-frontier and random-free runs), plus final Q and the area under the Q-vs-discovered
    curve per policy with bootstrap confidence intervals and paired comparisons; Q against
    scans and path length, and for a time-task sweep Q(t): Q against the robot's elapsed time
    over the budget (q_vs_time.png).

    Examples:

        nbv-gym report results/quick

        nbv-gym report results/paper --out paper-report

        nbv-gym report results/quick --pdf
    """
    from nbv_gym.core.outputs import writable_folder
    from nbv_gym.sweep.folder import ResultStore

    if out is not None:
        writable_folder(out)
    store = ResultStore(results)
    store.ensure_tables()
    _echo_set_aside(store.set_aside)
    built = _build_report(results, out)
    typer.echo(f"report: {built}")
    if pdf:
        from nbv_gym.reporting.pdf import write_pdf

        typer.echo(f"pdf: {write_pdf(built)}")


def _build_report(results: Path, out: Path | None = None) -> Path:
    """:func:`~nbv_gym.sweep.report.build_report`, saying on stderr that it runs and how long
    it took (it resamples and draws for tens of seconds)."""
    import time

    from nbv_gym.sweep.report import build_report

    typer.echo(
        f"building the report of {results} (figures, tables, bootstrap intervals)…", err=True
    )
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        built = build_report(results, out)
    _echo_set_aside([str(w.message) for w in caught if w.category is UserWarning])
    typer.echo(f"report built in {time.perf_counter() - start:.0f} s", err=True)
    return built


@contextlib.contextmanager
def resumable(kept: Path):
    """Around resumable work: SIGTERM stops it as Ctrl-C does (workers stopped, the folder
    unlocked); either way say that the finished runs are kept in ``kept`` and exit with 130."""
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        yield
    except KeyboardInterrupt:
        typer.secho(
            f"Interrupted. Finished runs are kept in {kept}; rerun the same command to resume.",
            err=True,
            fg="yellow",
        )
        raise SystemExit(130) from None


def _interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def _echo_set_aside(lines: list[str]) -> None:
    for line in lines:
        typer.secho(f"warning: {line}", err=True, fg="yellow")


def _json_summary(out: Path, summary, rows: list[dict], built: Path | None) -> dict:
    """What ``sweep --json`` prints: the counts, the failed runs, the tables, the report and
    the per-policy means (null: a policy with no finished run)."""
    return {
        "out": str(out),
        "total": summary.total,
        "resumed": summary.resumed,
        "finished": summary.finished,
        "failed": summary.failed,
        "failed_attempts": summary.failed_attempts,
        "wall_time_s": summary.wall_time_s,
        "backend": summary.backend,
        "tables": {name: str(path) for name, path in summary.tables.items()},
        "report": None if built is None else str(built),
        "policies": rows,
    }


def _echo_summary(summary, rows, to_stderr: bool = False) -> None:
    from nbv_gym.reporting.formatting import number_text  # a dash for a policy with no finished run

    done = summary.resumed + summary.finished
    typer.echo(
        f"{done}/{summary.total} runs finished ({summary.resumed} before, {summary.finished} now"
        f"{', on ' + summary.backend if summary.backend else ''}), "
        f"{len(summary.failed)} failed, {summary.failed_attempts} failed attempt(s); "
        f"{summary.wall_time_s:.0f} s",
        err=to_stderr,
    )
    header = (
        f"{'policy':<24}{'ok':>5}{'failed':>8}{'final Q':>10}{'discov.':>9}{'steps':>7}{'s/run':>7}"
    )
    lines = [header]
    for r in rows:
        lines.append(
            f"{r['policy'][:23]:<24}{r['ok']:>5}{r['failed']:>8}{number_text(r['q'], '.4f', 10)}"
            f"{number_text(r['discovered'], '.1%', 9)}{number_text(r['steps'], '.1f', 7)}"
            f"{number_text(r['wall_time_s'], '.1f', 7)}"
        )
    typer.echo("\n".join(lines), err=to_stderr)
