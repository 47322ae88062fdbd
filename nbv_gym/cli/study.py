"""``nbv-gym study wd`` and ``nbv-gym study empir3d``: typer commands the CLI registers."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from nbv_gym.cli.evaluate import EpsilonOption, RegionOption
from nbv_gym.cli.params import COUNT, NOISE_LEVEL, POSITIVE, POSITIVE_COUNT, SAMPLE_POINTS
from nbv_gym.core.outputs import check_owner
from nbv_gym.studies.wd_config import WdStudyConfig


def _listed(field: str, sep: str = " ") -> str:
    """The default of a tuple field of :class:`WdStudyConfig`, for a help text."""
    return sep.join(str(v) for v in getattr(WdStudyConfig, field))


study_app = typer.Typer(
    help="Reproduce the metric papers' studies (WD_occ, Empir3D) on our worlds or your data.",
    no_args_is_help=True,
    rich_markup_mode=None,
)


def _names(values: list[str] | None) -> tuple[str, ...] | None:
    """Repeated and comma-separated option values as one tuple (None when not given)."""
    if not values:
        return None
    return tuple(v.strip() for value in values for v in value.split(",") if v.strip())


@study_app.command("wd")
def study_wd(
    out: Annotated[Path, typer.Option(help="Study folder to write.")] = Path("studies/wd"),
    worlds: Annotated[
        list[str] | None,
        typer.Option(help="Worlds of Fig. 2 and Table II [default: the four pp1 worlds]."),
    ] = None,
    runs: Annotated[
        Path | None,
        typer.Option(
            help="Folder of `nbv-gym run --out` run folders for Fig. 4 [default: make runs "
            "into OUT/runs]. Runs without scans.npz are scored at their own resolution only."
        ),
    ] = None,
    share_worlds: Annotated[
        list[str] | None,
        typer.Option(
            help=f"Worlds explored for Fig. 4 [default: {_listed('share_worlds', ', ')}]."
        ),
    ] = None,
    noise: Annotated[
        list[int] | None,
        typer.Option(
            help=f"Noise levels of the runs [default: {_listed('noise_levels')}].",
            parser=NOISE_LEVEL,
        ),
    ] = None,
    resolution: Annotated[
        list[float] | None,
        typer.Option(
            help=f"Map resolutions of Fig. 4 [default: {_listed('resolutions_m')}].",
            parser=POSITIVE,
        ),
    ] = None,
    cuboids: Annotated[
        int | None,
        typer.Option(
            help=f"U_occ cuboids drawn per world (paper: 500) [default: {WdStudyConfig.cuboids}].",
            parser=POSITIVE_COUNT,
        ),
    ] = None,
    share_cuboids: Annotated[
        int | None,
        typer.Option(
            help="Observed U_occ cuboids drawn per map for Fig. 4 "
            f"[default: {WdStudyConfig.share_cuboids}].",
            parser=POSITIVE_COUNT,
        ),
    ] = None,
    policy: Annotated[
        str | None,
        typer.Option(help=f"Policy of the runs [default: {WdStudyConfig.policy}]."),
    ] = None,
    max_steps: Annotated[
        int | None,
        typer.Option(
            help=f"Scans per run after the first [default: {WdStudyConfig.max_steps}].",
            parser=POSITIVE_COUNT,
        ),
    ] = None,
    seed: Annotated[
        int | None,
        typer.Option(
            help=f"Base seed of every random draw [default: {WdStudyConfig.seed}].", parser=COUNT
        ),
    ] = None,
    report_only: Annotated[
        bool, typer.Option(help="Only rebuild OUT/report from OUT's tables.")
    ] = False,
) -> None:
    """The WD_occ paper's study: ideal vs random reconstructions (Fig. 2), the share of cuboids on
    which WD_occ and cov are informative on maps of exploration runs (Fig. 4), and the robustness
    Δ_k of Table II, with a verdict per claim in OUT/report/report.md.

    With the defaults (four pp1 worlds, six runs of 20 scans on pp1-cuboids and pp1-trees at
    noise 0, 1, 2, maps at 0.1 m and 0.05 m) it takes about 270 s of CPU time on 2 cores and
    about 5 GB of memory at its peak (the 0.05 m maps). Rerunning into the same OUT reuses its
    runs.

    Examples:

    \b
      nbv-gym study wd --out studies/wd
      nbv-gym study wd --out studies/wd-trees --worlds pp1-trees,pp2-trees \\
          --resolution 0.1
      nbv-gym study wd --out studies/mine --runs my_runs/ --cuboids 500
      nbv-gym study wd --out studies/wd --report-only
    """
    from nbv_gym.studies.wd_pipeline import run_wd_study
    from nbv_gym.studies.wd_report import build_wd_report

    check_owner(out, "study")
    if report_only:
        _done(build_wd_report(out))
        return
    overrides: dict[str, Any] = {
        "worlds": _names(worlds),
        "share_worlds": _names(share_worlds),
        "noise_levels": tuple(noise) if noise else None,
        "resolutions_m": tuple(resolution) if resolution else None,
        "cuboids": cuboids,
        "share_cuboids": share_cuboids,
        "policy": policy,
        "max_steps": max_steps,
        "seed": seed,
    }
    config = WdStudyConfig(**{k: v for k, v in overrides.items() if v is not None})
    _done(run_wd_study(config, out, runs))


@study_app.command("empir3d")
def study_empir3d(
    reference: Annotated[
        Path | None,
        typer.Argument(help="Reference cloud (.ply .pcd .npy .xyz) [default: see --world]."),
    ] = None,
    out: Annotated[Path, typer.Option(help="Study folder to write.")] = Path("studies/empir3d"),
    epsilon: EpsilonOption = None,
    region: RegionOption = None,
    world: Annotated[
        str, typer.Option(help="Without REFERENCE: sample this world's asset surfaces.")
    ] = "pp1-cuboids",
    points: Annotated[
        int, typer.Option(help="Without REFERENCE: points to sample.", parser=SAMPLE_POINTS)
    ] = 300_000,
    seed: Annotated[
        int, typer.Option(help="Seed of the sampling and the ablations.", parser=COUNT)
    ] = 0,
) -> None:
    """The Empir3D paper's ablations (Table I): down-sampling to 75 % and 50 %, Gaussian noise
    σ 0.01 and 0.02 m, crops to 40 % along X and Y, shifts of +0.1 m in X and 0.282 m in XY, each
    scored against the reference (D_c, D_h, Q_r, Q_a, Q_c, Q_t), with a verdict per ablation on
    whether it moves its own metric most, in OUT/report/report.md. Without REFERENCE the reference
    is a ground-truth cloud: points drawn on the asset surfaces of a benchmark world.

    Examples:

    \b
      nbv-gym study empir3d --out studies/empir3d
      nbv-gym study empir3d scan.ply --epsilon 0.05 --region 2 \\
          --out studies/my-scan
      nbv-gym study empir3d --world pp1-trees --points 500000 \\
          --out studies/empir3d-trees
    """
    from nbv_gym.metrics.evaluation import empir3d_config
    from nbv_gym.studies.empir3d_pipeline import run_empir3d_study

    config = empir3d_config(epsilon, region)
    check_owner(out, "study")
    _done(run_empir3d_study(reference, out, config, world, points, seed))


def _done(report: Path) -> None:
    """Print the report's verdict table and its path."""
    text = report.read_text(encoding="utf-8")
    start = text.find("| claim |")
    end = text.find("\n\n", start)
    if start >= 0:
        typer.echo(text[start : end if end >= 0 else None])
    typer.echo(f"report: {report}")
