"""TOML readers, world specs, sweep and training configs fed arbitrary text and mutated valid
configs: a config or a ConfigError (an NbvGymError), never another exception, a hang or a memory
blow-up."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from nbv_gym.configs import config_file
from nbv_gym.core.config import parse_toml, read_toml
from nbv_gym.rl.config import load_train_config
from nbv_gym.sweep.config import dumps_toml, load_sweep_config
from nbv_gym.worlds.spec import load_spec

ROOT = Path(__file__).resolve().parents[2]
BASES = {
    "world": ROOT / "nbv_gym" / "worlds" / "benchmark" / "pp1-trees.toml",
    "sweep": config_file("quick"),
    "train": config_file("ppo"),
}
KEYS = st.sampled_from(["name", "seed", "n_assets", "mix", "worlds", "noise", "policies", "x",
                        "repeats", "max_steps", "env", "learning", "n_steps", "trees"])  # fmt: skip
SCALARS = st.one_of(
    st.integers(-(2**63), 2**63 - 1),
    st.sampled_from([0, -1, 1, 2**31, 10**15, 2**63 - 1]),
    st.floats(),
    st.booleans(),
    st.text(max_size=12),
    st.sampled_from(["pp1-trees", "closest-frontier", "a:B", "random:mixed", "x.toml", "/", "."]),
)
VALUES = st.one_of(
    SCALARS, st.lists(SCALARS, max_size=4), st.dictionaries(KEYS, SCALARS, max_size=3)
)

pytestmark = pytest.mark.fuzz


@st.composite
def mutated_config(draw, base: dict) -> str:
    """TOML text of ``base`` with a few keys (at any depth) set to random values or dropped."""
    config = _copy(base)
    for _ in range(draw(st.integers(1, 4))):
        table = config
        while (nested := [k for k, v in table.items() if isinstance(v, dict)]) and draw(
            st.booleans()
        ):
            table = table[draw(st.sampled_from(nested))]
        key = draw(st.one_of(st.sampled_from(sorted(table) or ["x"]), KEYS))
        if draw(st.integers(0, 4)) == 0:
            table.pop(key, None)
        else:
            table[key] = draw(VALUES)
    return dumps_toml(config)


def _copy(value):
    return {k: _copy(v) for k, v in value.items()} if isinstance(value, dict) else value


#: The valid tables the mutations start from, read once (a file edited mid-run would make
#: Hypothesis's data generation inconsistent).
TABLES = {kind: parse_toml(path.read_text(), kind) for kind, path in BASES.items()}


LOADERS = {
    "world": load_spec,
    "sweep": load_sweep_config,
    "train": load_train_config,
}


@pytest.mark.parametrize("kind", sorted(BASES))
@given(data=st.data())
def test_mutated_configs(contract, folder, kind, data):
    text = data.draw(mutated_config(TABLES[kind]))
    path = folder / f"{kind}.toml"
    path.write_text(text)
    contract(lambda: LOADERS[kind](path), len(text))


@pytest.mark.parametrize("kind", sorted(BASES))
@given(content=st.one_of(st.binary(max_size=256), st.text(max_size=256).map(str.encode)))
def test_arbitrary_bytes(contract, folder, kind, content):
    path = folder / f"{kind}.toml"
    path.write_bytes(content)
    contract(lambda: read_toml(path, kind), len(content))
    contract(lambda: LOADERS[kind](path), len(content))
