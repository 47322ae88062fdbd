"""The configs shipped with the package, by name: sweeps, training, rl-zoo3 hyper-parameters.

Each config is a file in a folder named after its kind (``sweep/quick.toml``,
``train/ppo.toml``, ``rl-zoo3/rl-zoo3-ppo.yml``); its name is the file name without the
extension. Commands that take a config (``nbv-gym sweep``, ``nbv-gym train --config``) accept a
shipped name or a file path; :func:`config_file` is the one lookup between the two.
"""

from __future__ import annotations

import importlib.resources
from dataclasses import dataclass
from pathlib import Path

from nbv_gym.core.errors import ConfigError, UnknownNameError, missing_file

#: The kinds of shipped config, each a folder of this package.
KINDS = ("sweep", "train", "rl-zoo3")
_SUFFIXES = (".toml", ".yml")


@dataclass(frozen=True)
class ShippedConfig:
    """A config file shipped with the package: its ``name``, ``kind`` (one of :data:`KINDS`),
    ``path`` and ``summary`` (its first comment line)."""

    name: str
    kind: str
    path: Path

    @property
    def summary(self) -> str:
        """The config's one-line description: its file's first comment line."""
        first = self.path.read_text(encoding="utf-8").splitlines()[0]
        return first.lstrip("# ").strip()


def shipped_configs(kind: str | None = None) -> dict[str, ShippedConfig]:
    """Name → :class:`ShippedConfig` of every shipped config (of ``kind`` only, if given)."""
    found = {}
    for folder_kind in KINDS if kind is None else (kind,):
        folder = importlib.resources.files(__name__) / folder_kind
        for entry in sorted(folder.iterdir(), key=lambda p: p.name):
            if entry.name.endswith(_SUFFIXES):
                name = entry.name.rsplit(".", 1)[0]
                found[name] = ShippedConfig(name, folder_kind, Path(str(entry)))
    return found


def config_file(name_or_path: str | Path, kind: str | None = None) -> Path:
    """The file of a shipped config name (``"quick"``, of ``kind`` if given) or of a path.

    A value that names an existing file, or ends in ``.toml``/``.yml``, or holds a path
    separator is a path; anything else is looked up among the shipped configs, and an unknown
    name raises :class:`UnknownNameError` with the near misses.
    """
    text = str(name_or_path)
    path = Path(text)
    if path.is_dir():
        raise ConfigError(
            f"{text!r} is a folder, not a file. Give a config file or a shipped config name "
            "(see `nbv-gym configs list`)."
        )
    if path.is_file() or text.endswith(_SUFFIXES) or "/" in text or "\\" in text:
        if not path.is_file():
            raise ConfigError(
                f"Config file {text!r} {missing_file(path)}; give a file path or a shipped config "
                "name (see `nbv-gym configs list`)."
            )
        return path
    return shipped_config(text, kind).path


def shipped_config(name: str, kind: str | None = None) -> ShippedConfig:
    """The shipped config ``name`` (of ``kind`` if given); :class:`UnknownNameError` with the
    near misses if there is none."""
    shipped = shipped_configs(kind)
    if name not in shipped:
        raise UnknownNameError(f"{kind} config" if kind else "config", name, shipped)
    return shipped[name]
