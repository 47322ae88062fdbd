"""Strict loading of typed, frozen config dataclasses from plain dicts (TOML, JSON, CLI).

Every subsystem declares its config as a frozen dataclass whose fields carry the defaults and whose
``__post_init__`` checks the values. :func:`from_dict` builds one from a (nested) dict and rejects
unknown keys and wrong types with the dotted path of the offending key, at every depth.
"""

from __future__ import annotations

import dataclasses
import tomllib
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar, cast

from nbv_gym.core.errors import TOO_DEEP, ConfigError, missing_file

T = TypeVar("T")

#: The largest config or spec file read (bytes); they hold a few kB.
MAX_CONFIG_BYTES = 1 << 20


def from_dict(cls: type[T], data: Mapping[str, Any], path: str = "") -> T:
    """Build the dataclass ``cls`` from ``data``, recursing into nested dataclass fields.

    Raises :class:`ConfigError` naming the dotted key for unknown keys, wrong types and values that
    the dataclass's own checks reject.
    """
    if not isinstance(data, Mapping):
        raise ConfigError(f"{path or cls.__name__}: expected a table of keys, got {data!r}")
    fields = {f.name: f for f in dataclasses.fields(cast(Any, cls)) if f.init}
    unknown = sorted(set(data) - set(fields))
    if unknown:
        where = ", ".join(_join(path, k) for k in unknown)
        raise ConfigError(f"Unknown key {where}. Valid keys here: {', '.join(sorted(fields))}.")
    hints = typing.get_type_hints(cls)
    values = {name: _convert(hints[name], value, _join(path, name)) for name, value in data.items()}
    try:
        return cls(**values)
    except ConfigError as error:
        raise ConfigError(f"{path + ': ' if path else ''}{error}") from None
    except TypeError as error:
        raise ConfigError(f"{path or cls.__name__}: {error}") from None


def parse_toml(text: str, source: str) -> dict[str, Any]:
    """The table of TOML ``text``; :class:`ConfigError` naming ``source`` if it is not TOML."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise ConfigError(f"{source}: not valid TOML: {error}") from None
    except RecursionError:
        raise ConfigError(f"{source}: not valid TOML: {TOO_DEEP}.") from None


def read_toml(path: str | Path, kind: str) -> dict[str, Any]:
    """The table of the TOML file ``path``, a ``kind`` ("Sweep config", …) named in errors."""
    return parse_toml(read_text(path, kind), str(path))


def read_text(path: str | Path, kind: str) -> str:
    """The UTF-8 text of the config file ``path`` (at most :data:`MAX_CONFIG_BYTES`);
    :class:`ConfigError` naming the ``kind`` of file if it is missing, too large or not text."""
    from nbv_gym.core.inputs import InputFileError, read_input

    path = Path(path)
    if not path.exists() or path.is_dir():
        raise ConfigError(f"{kind} {str(path)!r} {missing_file(path)}.")
    try:
        return read_input(path, kind, MAX_CONFIG_BYTES).decode("utf-8")
    except InputFileError as error:
        raise ConfigError(str(error)) from None
    except UnicodeDecodeError as error:
        raise ConfigError(f"{kind} {str(path)!r} is not UTF-8 text (TOML is): {error}") from None


def to_dict(config: Any) -> dict[str, Any]:
    """The config as a nested dict of plain values (tuples become lists), for TOML or JSON."""
    return _plain(dataclasses.asdict(config))


def merge(base: Mapping[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` with the keys of ``extra`` set, nested tables merged key by key."""
    merged = dict(base)
    for key, value in extra.items():
        if isinstance(value, Mapping) and isinstance(merged.get(key), Mapping):
            merged[key] = merge(merged[key], value)
        else:
            merged[key] = value
    return merged


def check(condition: bool, key: str, message: str) -> None:
    """Raise :class:`ConfigError` for ``key`` unless ``condition`` holds (for ``__post_init__``)."""
    if not condition:
        raise ConfigError(f"{key}: {message}")


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _convert(hint: Any, value: Any, path: str) -> Any:
    origin = typing.get_origin(hint)
    if isinstance(hint, type) and dataclasses.is_dataclass(hint):
        return from_dict(hint, value, path)
    if origin in (typing.Union, types.UnionType):
        return _convert_union(typing.get_args(hint), value, path)
    if origin is tuple:
        return _convert_tuple(typing.get_args(hint), value, path)
    if origin in (dict, Mapping):
        return _convert_mapping(typing.get_args(hint), value, path)
    if origin is typing.Literal:
        if value not in typing.get_args(hint):
            choices = ", ".join(repr(a) for a in typing.get_args(hint))
            raise ConfigError(f"{path}: expected one of {choices}, got {value!r}")
        return value
    return _convert_scalar(hint, value, path)


def _convert_union(args: tuple[Any, ...], value: Any, path: str) -> Any:
    if value is None and type(None) in args:
        return None
    errors = []
    for arg in (a for a in args if a is not type(None)):
        try:
            return _convert(arg, value, path)
        except ConfigError as error:
            errors.append(str(error))
    raise ConfigError(errors[0] if len(errors) == 1 else f"{path}: {value!r} fits none of {args}")


def _convert_tuple(args: tuple[Any, ...], value: Any, path: str) -> tuple[Any, ...]:
    if not isinstance(value, (list, tuple)):
        raise ConfigError(f"{path}: expected a list, got {value!r}")
    if len(args) == 2 and args[1] is Ellipsis:
        return tuple(_convert(args[0], v, f"{path}[{i}]") for i, v in enumerate(value))
    if len(value) != len(args):
        raise ConfigError(f"{path}: expected {len(args)} values, got {len(value)}: {value!r}")
    return tuple(
        _convert(a, v, f"{path}[{i}]") for i, (a, v) in enumerate(zip(args, value, strict=True))
    )


def _convert_mapping(args: tuple[Any, ...], value: Any, path: str) -> dict[Any, Any]:
    if not isinstance(value, Mapping):
        raise ConfigError(f"{path}: expected a table, got {value!r}")
    key_type, value_type = args if args else (Any, Any)
    return {
        _convert(key_type, k, path): _convert(value_type, v, _join(path, str(k)))
        for k, v in value.items()
    }


def _convert_scalar(hint: Any, value: Any, path: str) -> Any:
    if hint is Any:
        return value
    if hint is float and isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    if hint is int and isinstance(value, bool):
        raise ConfigError(f"{path}: expected an integer, got {value!r}")
    if isinstance(hint, type) and not isinstance(value, hint):
        raise ConfigError(f"{path}: expected {hint.__name__}, got {type(value).__name__} {value!r}")
    return value
