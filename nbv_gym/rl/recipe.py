"""A staged training recipe — a training config with an ``[imitation]`` table, such as the shipped
``imitation-time`` — run as one resumable job in one folder: DAgger labels of a privileged
teacher and imitation, iteration by iteration, then RL from the imitated weights.

The run folder ``out``::

    recipe.toml                       the resolved config (a rerun with another one is refused)
    labels/iter-<i>/episode-<k>.npz   the label shards of iteration i (nbv_gym.rl.labelfile)
    imitation/iter-<i>/               checkpoint.pt, metrics.csv and model.zip of iteration i
    rl/                               nbv-gym train's run folder, started from the last model.zip

Stages, in order: for each iteration ``i``, ``labels i`` (:func:`~nbv_gym.rl.labels.collect`:
the teacher acting with probability β_i, the model of ``imitation i − 1`` otherwise) and
``imitation i`` (:func:`~nbv_gym.rl.imitation.imitate` on the labels of iterations 0…i, from
the weights of ``imitation i − 1``); then ``rl`` (:func:`~nbv_gym.rl.train.train` with
``init_model`` the last imitation's model). Each stage is resumable — shards, epoch
checkpoints, RL checkpoints — and a finished stage is skipped: killed at any point, the same
command goes on where it stopped.
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

from nbv_gym.core.errors import ConfigError
from nbv_gym.core.outputs import atomic, write_text
from nbv_gym.core.progress import say
from nbv_gym.rl.config import TrainConfig, load_train_config
from nbv_gym.rl.imitation import imitate
from nbv_gym.rl.labels import check_teacher, collect, shard_path
from nbv_gym.rl.train import FINAL_MODEL, TrainingInterrupted, dumps_toml, train
from nbv_gym.worlds import load_spec
from nbv_gym.worlds.distribution import is_distribution

RECIPE = "recipe.toml"
RL = "rl"
#: Config keys that say where a recipe runs, not what it computes: a rerun may change them.
WHERE_KEYS = ("scheduler", "device", "torch_threads")


def run_recipe(
    config: TrainConfig,
    out: str | Path,
    progress: bool = True,
    verbose: int = 0,
    time_limit_s: float | None = None,
) -> Path:
    """Run (or go on with) the recipe ``config`` in the folder ``out``; the final model's path.
    ``time_limit_s`` limits the RL stage as ``nbv-gym train --time-limit`` does."""
    imitation = config.imitation
    if imitation is None:
        raise ConfigError("the config has no [imitation] table: it is no staged recipe")
    out = Path(out)
    check_teacher(config)
    for world in dict.fromkeys((*config.train_worlds, *config.eval_worlds)):
        if not is_distribution(world):
            load_spec(world)  # a misspelt world is refused now, not at the RL stage hours later
    _claim(out, config)
    model = None
    for i in range(imitation.iterations):
        say(f"stage labels {i} of {imitation.iterations} iteration(s)")
        collect(config, labels_folder(out, i), i, model, progress)
        train_paths, validation = split(config, out, i)
        say(f"stage imitation {i}: {len(train_paths)} training and {len(validation)} "
            "validation episodes")  # fmt: skip
        model = imitate(config, i, train_paths, validation, imitation_folder(out, i), model,
                        progress)  # fmt: skip
    assert model is not None
    return reinforce(config, out, model, progress, verbose, time_limit_s)


def labels_folder(out: Path, iteration: int) -> Path:
    """The folder of iteration ``iteration``'s label shards."""
    return out / "labels" / f"iter-{iteration}"


def imitation_folder(out: Path, iteration: int) -> Path:
    """The folder of iteration ``iteration``'s imitation."""
    return out / "imitation" / f"iter-{iteration}"


def split(config: TrainConfig, out: Path, iteration: int) -> tuple[list[Path], list[Path]]:
    """The training and validation shards of iterations 0…``iteration`` (DAgger's aggregate)."""
    imitation = config.imitation
    assert imitation is not None
    train_paths: list[Path] = []
    validation: list[Path] = []
    for i in range(iteration + 1):
        for k in range(imitation.episodes_per_iteration):
            path = shard_path(labels_folder(out, i), k)
            (validation if imitation.is_validation(k) else train_paths).append(path)
    return train_paths, validation


def reinforce(
    config: TrainConfig,
    out: Path,
    start: Path,
    progress: bool = True,
    verbose: int = 0,
    time_limit_s: float | None = None,
) -> Path:
    """The RL stage: train ``config`` (its imitation table dropped) from the weights of the
    model zip ``start`` into ``out/rl``, going on from its last checkpoint; the final model."""
    folder = out / RL
    final = folder / FINAL_MODEL
    if final.exists():
        return final
    resume = latest_checkpoint(folder)
    if resume is not None and _steps(resume) >= config.total_timesteps:  # killed before the end
        with atomic(final, "wb") as file:
            file.write(resume.read_bytes())
        return final
    say(f"stage rl: {config.total_timesteps:,} steps from {start}"
        + (f", going on from {resume}" if resume else ""))  # fmt: skip
    settings = replace(config, imitation=None, init_model=str(start))
    try:
        train(settings, folder, resume, progress, verbose, time_limit_s)
    except TrainingInterrupted:
        raise TrainingInterrupted(
            f"interrupted (Ctrl-C); the RL stage's model so far is saved in {folder}/checkpoints. "
            "Rerun the same command to go on."
        ) from None
    return final


def latest_checkpoint(folder: Path) -> Path | None:
    """The checkpoint of the most steps in ``folder/checkpoints``, or None."""
    found = [path for path in (folder / "checkpoints").glob("model_*_steps.zip")
             if _steps(path) >= 0]  # fmt: skip
    return max(found, key=_steps) if found else None


def _steps(checkpoint: Path) -> int:
    """The steps in a checkpoint's name ``model_<steps>_steps.zip`` (−1 for another name)."""
    match = re.fullmatch(r"model_(\d+)_steps\.zip", checkpoint.name)
    return int(match.group(1)) if match else -1


def _claim(out: Path, config: TrainConfig) -> None:
    """Write ``out/recipe.toml``, or check that the recipe there is ``config`` (but for
    :data:`WHERE_KEYS` and another task's budget or truncation, which its episodes never read:
    a folder written before ``budget_scans`` split from ``max_steps`` goes on);
    :class:`ConfigError` naming the keys that differ."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / RECIPE
    if not path.exists():
        stages = [name for name in ("labels", "imitation", RL) if (out / name).exists()]
        if stages:  # its labels and models came from a config no longer known
            raise ConfigError(
                f"{out} holds a recipe run's {', '.join(stages)} but no {RECIPE}: the config they "
                f"came from is unknown; put its {RECIPE} back, or give another --out."
            )
        write_text(path, dumps_toml(config.file_dict()))
        return
    earlier, now = _flat(load_train_config(path).file_dict()), _flat(config.file_dict())
    differ = sorted(k for k in earlier.keys() | now.keys()
                    if earlier.get(k) != now.get(k) and k not in WHERE_KEYS
                    and config.task.shapes(k))  # fmt: skip
    if differ:
        raise ConfigError(
            f"{out} holds a recipe run with another config ({', '.join(differ[:4])} differ); "
            "rerun it with its own config (recipe.toml there), or give another --out."
        )


def _flat(data: dict, prefix: str = "") -> dict:
    flat = {}
    for key, value in data.items():
        if isinstance(value, dict):
            flat.update(_flat(value, f"{prefix}{key}."))
        else:
            flat[prefix + key] = value
    return flat
