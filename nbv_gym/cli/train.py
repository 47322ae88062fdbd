"""``nbv-gym train``: train an RL exploration agent (torch and SB3 imported inside the command)."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Annotated

import typer

from nbv_gym.cli.options import LidarOption
from nbv_gym.cli.params import COUNT, POSITIVE, POSITIVE_COUNT


def train(
    config: Annotated[
        str,
        typer.Option(
            "--config",
            help="A shipped training config (ppo; see nbv-gym configs list) or the path of a "
            "training config file (TOML).",
        ),
    ],
    timesteps: Annotated[
        int | None,
        typer.Option(
            help="Total environment steps (overrides total_timesteps).", parser=POSITIVE_COUNT
        ),
    ] = None,
    out: Annotated[
        Path | None, typer.Option(help="Run folder (default: runs/<config name>).")
    ] = None,
    resume: Annotated[
        Path | None,
        typer.Option(help="Checkpoint or model zip to continue from (keeps its step count)."),
    ] = None,
    force: Annotated[
        bool,
        typer.Option(
            help="Replace an earlier training in --out (its files stay until the new one finished)."
        ),
    ] = False,
    n_envs: Annotated[
        int | None,
        typer.Option(help="Parallel environments (overrides n_envs).", parser=POSITIVE_COUNT),
    ] = None,
    batch_size: Annotated[
        int | None,
        typer.Option(
            help="PPO's minibatch size, at most n_steps · n_envs (overrides learning.batch_size; "
            "e.g. 128 with --n-envs 1).",
            parser=POSITIVE_COUNT,
        ),
    ] = None,
    seed: Annotated[int | None, typer.Option(help="Seed (overrides seed).", parser=COUNT)] = None,
    lidar: LidarOption = None,
    scheduler: Annotated[
        str | None,
        typer.Option(
            help="Run the environments on a Dask cluster: a scheduler address (tcp://HOST:8786, "
            "tls://… with Dask's TLS settings) or 'local' for a LocalCluster here (overrides "
            "scheduler). The learner stays in this process."
        ),
    ] = None,
    device: Annotated[
        str | None, typer.Option(help="Torch device: cpu, cuda or auto (overrides device).")
    ] = None,
    time_limit: Annotated[
        float | None,
        typer.Option(
            "--time-limit",
            help="Stop after this many minutes of training, then save as if finished.",
            parser=POSITIVE,
        ),
    ] = None,
    eval_every: Annotated[
        int | None,
        typer.Option(
            help="Evaluate every N environment steps (overrides eval_every_steps; 0: never).",
            parser=COUNT,
        ),
    ] = None,
    progress: Annotated[bool, typer.Option(help="Show a progress bar.")] = True,
    verbose: Annotated[bool, typer.Option(help="Print SB3's training tables.")] = False,
) -> None:
    """Train a stable-baselines3 agent (MaskablePPO by default) on the training worlds, with
    periodic checkpoints and masked evaluation on the evaluation worlds.

    With --scheduler the environments live on the workers of a Dask cluster (one actor per
    worker holding its share of --n-envs), the learner here (--device cuda where this machine
    has a GPU); a lost worker's environments are rebuilt on the others and their episodes end
    as "worker lost" in episodes.csv. See docs/rl-cluster.md.

    The run folder holds config.toml, system_info.txt, logs/run-<k>/ (progress.csv and
    TensorBoard events), checkpoints/, best_model.zip (best evaluation), final_model.zip,
    episodes.csv (every training episode) and learning_curve.png. A folder holding an earlier
    training is refused unless --resume continues it or --force replaces it; with --force the
    new files replace the old ones only when the new training finished.
    A config with an [imitation] table (imitation-time) is a staged recipe: labels of a
    privileged teacher (DAgger), imitation, then RL from the imitated weights, in --out; killed
    at any point, the same command goes on (docs/rl.md#imitation).
    A model runs as a policy named sb3:PATH in nbv-gym run and in sweep configs. A model zip
    is code (SB3 unpickles it): load only models you trust.

    Examples:

    \b
      nbv-gym train --config ppo
      nbv-gym train --config ppo --timesteps 5000 \\
          --out runs/ppo-short
      nbv-gym train --config ppo --eval-every 2000
      nbv-gym train --config ppo --n-envs 1 --batch-size 128
      nbv-gym train --config ppo --lidar vlp-16 --out runs/ppo-vlp16
      nbv-gym train --config ppo --n-envs 16 \\
          --device cuda --time-limit 9
      nbv-gym train --config ppo --scheduler local --n-envs 4
      nbv-gym train --config ppo --n-envs 64 --device cuda \\
          --scheduler tls://scheduler.lab:8786
      nbv-gym train --config ppo \\
          --resume runs/ppo/checkpoints/model_8000_steps.zip
      nbv-gym train --config ppo --force  # replace runs/ppo
      nbv-gym train --config imitation-time --out runs/imitation
      tensorboard --logdir runs/ppo/logs
      nbv-gym run --policy sb3:runs/ppo/best_model.zip --world pp3-trees
    """
    from nbv_gym.configs import config_file
    from nbv_gym.core.outputs import claim_folder
    from nbv_gym.rl.config import load_train_config
    from nbv_gym.rl.train import check_resume
    from nbv_gym.sweep.backends import reach_scheduler

    overrides = {"total_timesteps": timesteps, "n_envs": n_envs, "seed": seed,
                 "eval_every_steps": eval_every, "device": device,
                 "scheduler": scheduler, "learning.batch_size": batch_size,
                 "lidar": lidar}  # fmt: skip
    config_path = config_file(config, "train")
    settings = load_train_config(config_path, overrides)
    out = out or Path("runs") / config_path.stem
    if settings.imitation is not None:
        _recipe(settings, out, force or resume is not None, progress, verbose, time_limit)
        return
    earlier = _check_train_folder(out, force, resume)
    check_resume(settings, resume)  # a resume that cannot go on fails before anything is written
    reach_scheduler(settings.scheduler or None)
    claim_folder(out, "train")
    where = f" on {settings.scheduler}" if settings.scheduler else ""
    typer.echo(
        f"{settings.algorithm}: {settings.total_timesteps:,} steps, {settings.n_envs} envs{where}, "
        f"train on {len(settings.train_worlds)} worlds, evaluate on "
        f"{len(settings.eval_worlds)} → {out}",
        err=True,
    )
    kwargs = {"resume": resume, "progress_bar": progress, "verbose": int(verbose),
              "time_limit_s": None if time_limit is None else 60 * time_limit}  # fmt: skip
    steps = _train_into(settings, out, earlier and force and resume is None, kwargs)
    _summary(out, steps)


def _recipe(settings, out: Path, refused: bool, progress: bool, verbose: bool, time_limit) -> None:
    """Run or go on with the staged recipe ``settings`` in ``out`` (nbv_gym.rl.recipe)."""
    from nbv_gym.core.outputs import OutputError, check_owner, claim_folder
    from nbv_gym.rl.recipe import run_recipe
    from nbv_gym.rl.train import earlier_training

    if refused:
        raise OutputError(
            "--resume and --force do not apply to a staged recipe (a config with [imitation]): "
            "rerun the same command to go on where it stopped, or give another --out."
        )
    check_owner(out, "train")
    if earlier := earlier_training(out):
        raise OutputError(
            f"--out {out} holds a plain training ({', '.join(earlier[:3])}); give the recipe "
            "another folder."
        )
    claim_folder(out, "train")
    imitation = settings.imitation
    typer.echo(
        f"recipe: {imitation.iterations} × ({imitation.episodes_per_iteration} labelled "
        f"episodes of {imitation.teacher} + imitation), then {settings.algorithm} for "
        f"{settings.total_timesteps:,} steps → {out}",
        err=True,
    )
    limit = None if time_limit is None else 60 * time_limit
    final = run_recipe(settings, out, progress, int(verbose), limit)
    with zipfile.ZipFile(final) as archive:  # SB3's data JSON holds the step count
        steps = json.loads(archive.read("data"))["num_timesteps"]
    _summary(final.parent, steps)


def _check_train_folder(out: Path, force: bool, resume: Path | None) -> bool:
    """Whether ``out`` holds an earlier training, after checking that it is not another
    command's folder and that an earlier training is continued (``--resume``) or replaced
    (``--force``), never overwritten unasked."""
    from nbv_gym.core.outputs import OutputError, check_owner
    from nbv_gym.rl.recipe import RECIPE
    from nbv_gym.rl.train import earlier_training

    check_owner(out, "train")
    if (out / RECIPE).exists():
        raise OutputError(
            f"--out {out} holds a staged recipe run ({RECIPE}; its RL stage is {out / 'rl'}); "
            "give a plain training another folder."
        )
    earlier = earlier_training(out)
    if earlier and not (force or resume):
        raise OutputError(
            f"--out {out} holds an earlier training ({', '.join(earlier[:3])}"
            f"{', …' if len(earlier) > 3 else ''}); pass --resume CHECKPOINT to continue it, "
            "--force to replace it (its files stay until the new training finished), or give "
            "another folder."
        )
    if force and resume:
        raise OutputError("--force and --resume: give one (replace the training or continue it).")
    if earlier and resume and not Path(resume).resolve().is_relative_to(out.resolve()):
        raise OutputError(
            f"--resume {resume} is not a checkpoint of the training in --out {out}, which it "
            "would overwrite; continue a training in its own folder, or give a new folder."
        )
    return bool(earlier)


def _train_into(settings, out: Path, staged: bool, kwargs: dict) -> int:
    """Train into ``out`` (into a staged sibling whose files replace ``out``'s when training
    finished, if ``staged``) and return the model's step count."""
    from nbv_gym.core.outputs import staged_folder
    from nbv_gym.rl.train import RUN_FILES, TrainingInterrupted
    from nbv_gym.rl.train import train as train_agent

    if not staged:
        return train_agent(settings, out, **kwargs).num_timesteps
    try:
        with staged_folder(out, RUN_FILES) as staging:
            return train_agent(settings, staging, **kwargs).num_timesteps
    except (TrainingInterrupted, KeyboardInterrupt):
        raise TrainingInterrupted(
            f"interrupted (Ctrl-C); the earlier training in {out} is unchanged (the new one "
            "was not finished, so it replaced nothing)."
        ) from None


def _summary(out: Path, steps: int) -> None:
    """The final table: steps, best evaluation return and the model files."""
    import numpy as np

    rows = [("steps", f"{steps:,}")]
    evaluations = out / "eval" / "evaluations.npz"
    if evaluations.exists():
        results = np.load(evaluations)["results"].mean(axis=1)
        rows.append(("best eval return", f"{results.max():.3f} (of {len(results)} evaluations)"))
    for name in ("best_model.zip", "final_model.zip", "learning_curve.png"):
        if (out / name).exists():
            rows.append((name, str(out / name)))
    for key, value in rows:
        typer.echo(f"{key:<18} {value}")
