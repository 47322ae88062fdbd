"""What a stable-baselines3 model zip claims to be, read before anything in it is unpickled.

An SB3 zip holds a ``data`` member (JSON) next to the network weights. Most JSON values are plain;
the classes and spaces are cloudpickled, with a readable description beside each pickle (the
``:type:`` string, the module of a class, the repr of a space's parts). :func:`describe_model`
parses the JSON alone and refuses files that are not an SB3 zip, whose policy does not come from
stable-baselines3, sb3-contrib or nbv-gym, or whose saved spaces are not those of
``Explore-v0``; only then does SB3's ``load`` unpickle. This catches wrong and broken files; it
does not make a hostile file safe, since its readable descriptions can lie about its pickles:
loading a model runs code from it.
"""

from __future__ import annotations

import json
import math
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from nbv_gym.core.errors import missing_file
from nbv_gym.policies import PolicyError

#: The largest ``data`` member read (bytes); nbv-gym's models hold a few kB.
MAX_DATA_BYTES = 16 << 20
#: Modules a saved policy class may come from.
POLICY_MODULES = (
    "stable_baselines3.common.policies",
    "sb3_contrib.common.maskable.policies",
    "nbv_gym.rl.extractor",
)
#: The largest saved Box rebuilt with its shape (elements).
MAX_BOX_SIZE = 1 << 20
_MASKABLE_BUFFERS = "sb3_contrib.common.maskable.buffers"
#: Saved Discrete action spaces: Gymnasium's, and Explore-v0's GoalSpace (a Discrete whose
#: sample() draws valid goals), which models trained on the registered ids save.
_DISCRETE = (
    "<class 'gymnasium.spaces.discrete.Discrete'>",
    "<class 'nbv_gym.env.explore.GoalSpace'>",
)
_DICT = "<class 'gymnasium.spaces.dict.Dict'>"
#: ``'name': Kind(...)`` entries of a saved Dict space's ``spaces`` repr.
_ENTRY = re.compile(r"'(?P<key>[^']*)': (?P<kind>\w+)\((?P<body>.*?)\)(?=, '|\}$)")


@dataclass(frozen=True)
class ModelDescription:
    """A model zip's algorithm (``"MaskablePPO"``, ``"PPO"`` or ``"A2C"``) and its spaces as
    :func:`~nbv_gym.rl.agent.check_spaces` reads them (gymnasium spaces rebuilt from the JSON;
    Box bounds are not kept)."""

    algorithm: str
    action_space: Any
    observation_space: Any


#: Zips a packaged folder holds that are not models: rl-zoo3's archive of the run's metrics.
NOT_MODELS = ("train_eval_metrics.zip",)


def model_file(path: Path) -> Path:
    """``path``, or the one model zip in the folder ``path`` (a model packaged by
    ``nbv-gym package-model``); :class:`PolicyError` if the folder holds none or several."""
    if not path.is_dir():
        return path
    zips = sorted(z for z in path.glob("*.zip") if z.name not in NOT_MODELS)
    if len(zips) != 1:
        found = ", ".join(z.name for z in zips) or "none"
        raise PolicyError(
            f"{str(path)!r} is a folder: expected one model .zip in it (a folder written by "
            f"nbv-gym package-model), found {found}. Name the zip: sb3:FOLDER/MODEL.zip."
        )
    return zips[0]


def check_model_file(path: Path) -> None:
    """Raise :class:`PolicyError` unless ``path`` is an SB3 model zip."""
    if not path.is_file():
        raise PolicyError(
            f"No SB3 model at {str(path)!r} (it {missing_file(path)}): expected a .zip saved by "
            "nbv-gym train."
        )
    if not zipfile.is_zipfile(path):
        raise PolicyError(f"{str(path)!r} is not an SB3 model: expected a .zip file.")


def describe_model(path: Path) -> ModelDescription:
    """The algorithm and spaces the ``data`` JSON of the SB3 zip at ``path`` declares, without
    unpickling; :class:`PolicyError` naming the file if it is not an SB3 model zip."""
    data = read_model_data(path)
    return ModelDescription(
        _algorithm(data, path),
        _action_space(data.get("action_space"), path),
        _observation_space(data.get("observation_space"), path),
    )


def read_model_data(path: Path) -> dict[str, Any]:
    """The parsed ``data`` JSON of the zip at ``path`` (at most :data:`MAX_DATA_BYTES`)."""
    from nbv_gym.core.arrayfiles import MAX_NPZ_BYTES
    from nbv_gym.core.inputs import open_input

    try:
        with (
            open_input(path, "Model file", MAX_NPZ_BYTES) as file,
            zipfile.ZipFile(file) as archive,
        ):
            info = archive.getinfo("data")
            if info.file_size > MAX_DATA_BYTES:
                raise _not_a_model(path, f"its data member has {info.file_size} bytes")
            data = json.loads(archive.read(info))
    except KeyError:
        raise _not_a_model(path, "the zip has no 'data' member") from None
    except (zipfile.BadZipFile, OSError, EOFError, ValueError, RuntimeError) as error:
        raise _not_a_model(path, f"unreadable ({type(error).__name__}: {error})") from None
    if not isinstance(data, dict):
        raise _not_a_model(path, "its data member is not a JSON object")
    return data


def _not_a_model(path: Path, problem: str) -> PolicyError:
    return PolicyError(
        f"{str(path)!r} is not a stable-baselines3 model zip: {problem}. Expected a .zip saved "
        "by nbv-gym train."
    )


def _algorithm(data: dict[str, Any], path: Path) -> str:
    """MaskablePPO (a maskable rollout buffer), PPO (``n_epochs``) or A2C."""
    module = _readable(data, "policy_class", path).get("__module__")
    if module not in POLICY_MODULES:
        raise PolicyError(
            f"{str(path)!r}: its policy class comes from {module!r}, not from one of "
            f"{', '.join(POLICY_MODULES)}; refusing to unpickle it. Train models with nbv-gym train."
        )
    buffer = data.get("rollout_buffer_class")
    if isinstance(buffer, dict) and buffer.get("__module__") == _MASKABLE_BUFFERS:
        return "MaskablePPO"
    return "PPO" if "n_epochs" in data else "A2C"


def _readable(data: dict[str, Any], key: str, path: Path) -> dict[str, Any]:
    entry = data.get(key)
    if not isinstance(entry, dict) or not isinstance(entry.get(":type:"), str):
        raise _not_a_model(path, f"its data has no saved {key}")
    return entry


def _action_space(entry: Any, path: Path) -> Any:
    """``Discrete(n)`` for a saved Discrete space, else the saved type's name."""
    from gymnasium import spaces

    entry = _readable({"action_space": entry}, "action_space", path)
    n = entry.get("n")
    if entry[":type:"] in _DISCRETE and isinstance(n, str) and n.isdecimal() and len(n) < 10:
        return spaces.Discrete(int(n))
    return entry[":type:"]


def _observation_space(entry: Any, path: Path) -> Any:
    """A Dict of Boxes with the saved keys and shapes for a saved Dict space, else the saved
    type's name; an entry that is not a Box gets the shape ``()``."""
    from gymnasium import spaces

    entry = _readable({"observation_space": entry}, "observation_space", path)
    text = entry.get("spaces")
    if entry[":type:"] != _DICT or not isinstance(text, str):
        return entry[":type:"]
    return spaces.Dict({m["key"]: _box(m["kind"], m["body"]) for m in _ENTRY.finditer(text)})


def _box(kind: str, body: str):
    """A float32 Box (its bounds are not kept) of the shape a saved space's repr ends with."""
    import numpy as np
    from gymnasium import spaces

    shapes = re.findall(r"\(([\d, ]*)\)", body) if kind == "Box" else []
    sizes = [int(s) for s in shapes[-1].replace(" ", "").split(",") if s] if shapes else []
    if math.prod(sizes) > MAX_BOX_SIZE:
        sizes = []  # larger than any layer: a wrong shape either way
    return spaces.Box(-1.0, 1.0, tuple(sizes), dtype=np.float32)
