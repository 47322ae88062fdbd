"""``nbv-gym package-model``: a trained agent as a folder ready for a model hub."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def package_model(
    run_dir: Annotated[
        str,
        typer.Argument(
            help="A training run folder, a model .zip (its .toml beside it) or a shipped "
            "model (ppo-budget).",
            metavar="RUN_DIR",
        ),
    ],
    out: Annotated[Path, typer.Option(help="Folder to write (created if missing).")],
    model: Annotated[
        str | None,
        typer.Option(help="Model zip of the run folder [default: final_model.zip]."),
    ] = None,
    episodes: Annotated[
        int, typer.Option(help="Evaluation episodes per held-out world.", min=1)
    ] = 3,
    seed: Annotated[int, typer.Option(help="Seed of the first evaluation episode.", min=0)] = 0,
) -> None:
    """Package a trained agent for a model hub: the model zip, its training config, a model
    card README.md (YAML metadata in the SB3 hub's conventions: library_name, tags with the env
    id, model-index with the metrics), results.json, replay.gif and learning_curve.png.

    The agent is evaluated deterministically with action masks (MaskablePPO) on the held-out
    worlds of its config, under the task, noise and budget it was trained for; the card gives
    means with 95 % bootstrap intervals. Nothing is uploaded: push the folder with the hub's
    own tools. The folder loads back as a policy: sb3:DIR. A model zip is code (SB3 unpickles
    it): package and load only models you trust.

    Examples:

    \b
      nbv-gym package-model runs/ppo --out hub/ppo-budget
      nbv-gym package-model runs/ppo --model best_model.zip --out hub/ppo-best
      nbv-gym package-model ppo-budget --out hub/ppo-budget --episodes 5
      nbv-gym run --policy sb3:hub/ppo-budget --world pp3-trees
    """
    from nbv_gym.rl.hub import find_source, package

    source = find_source(run_dir, model)
    typer.echo(f"packaging {source.model} → {out} ({episodes} episode(s) per world)", err=True)
    results = package(source, out, episodes, seed, lambda line: typer.echo(line, err=True))
    q = results["overall"]["q"]
    typer.echo(
        f"mean_reward {results['mean_reward']:.3f} +/- {results['std_reward']:.3f} over "
        f"{results['n_eval_episodes']} episodes; Q {q['mean']:.4f} "
        f"[{q['low']:.4f}, {q['high']:.4f}]"
    )
    typer.echo(f"model folder: {out}")
