"""SB3 model zips with arbitrary and mutated ``data`` JSON: a description or a PolicyError (an
NbvGymError) from :func:`describe_model`, which never unpickles, never another exception."""

from __future__ import annotations

import json
import zipfile

import pytest
from hypothesis import given
from hypothesis import strategies as st

from nbv_gym.rl.modelfile import describe_model

BOX = "Box(0.0, 1.0, (3600,), float32)"
#: The readable part of a MaskablePPO model's data JSON, as SB3 writes it (pickles left out).
DATA = {
    "policy_class": {":type:": "<class 'abc.ABCMeta'>", "__module__": "nbv_gym.rl.extractor"},
    "rollout_buffer_class": {
        ":type:": "<class 'abc.ABCMeta'>",
        "__module__": "sb3_contrib.common.maskable.buffers",
    },
    "observation_space": {
        ":type:": "<class 'gymnasium.spaces.dict.Dict'>",
        "spaces": f"{{'free': {BOX}, 'known': {BOX}, 'state': Box(-2.0, 2.0, (6,), float32)}}",
    },
    "action_space": {":type:": "<class 'gymnasium.spaces.discrete.Discrete'>", "n": "3600"},
    "n_epochs": 10,
}
JSON = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(), st.floats(allow_nan=False), st.text()),
    lambda children: (
        st.lists(children, max_size=3) | st.dictionaries(st.text(), children, max_size=3)
    ),
    max_leaves=8,
)
TEXT = st.one_of(
    st.text(max_size=40),
    st.sampled_from(["3600", "99999999999999999999", "-1", "{'a': Box(0, 1, (999999999999,), f)}",
                     "{'x': Discrete(3)}", "{'known': Box(0.0, 1.0, (, float32)}"]),
)  # fmt: skip

pytestmark = pytest.mark.fuzz


@st.composite
def mutated_data(draw) -> bytes:
    """``DATA`` with a few readable fields replaced by random JSON or text, or dropped."""
    data = json.loads(json.dumps(DATA))
    for _ in range(draw(st.integers(1, 3))):
        if not data:
            break
        entry = draw(st.sampled_from(sorted(data)))
        if isinstance(data[entry], dict) and data[entry] and draw(st.booleans()):
            field = draw(st.sampled_from(sorted(data[entry])))
            data[entry][field] = draw(st.one_of(TEXT, JSON))
        elif draw(st.booleans()):
            data.pop(entry)
        else:
            data[entry] = draw(JSON)
    return json.dumps(data).encode()


def _describe(contract, folder, members: dict[str, bytes]) -> None:
    path = folder / "model.zip"
    with zipfile.ZipFile(path, "w") as archive:
        for name, content in members.items():
            archive.writestr(name, content)
    contract(lambda: describe_model(path), sum(map(len, members.values())))


@given(mutated_data())
def test_mutated_model_data(contract, folder, data):
    _describe(contract, folder, {"data": data})


@given(st.one_of(JSON.map(lambda v: json.dumps(v).encode()), st.binary(max_size=128)))
def test_arbitrary_model_data(contract, folder, data):
    _describe(contract, folder, {"data": data})


@given(st.binary(max_size=256))
def test_arbitrary_model_files(contract, folder, content):
    path = folder / "model.zip"
    path.write_bytes(content)
    contract(lambda: describe_model(path), len(content))


def test_the_unmutated_data_describes_its_model(folder):
    path = folder / "model.zip"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("data", json.dumps(DATA))
    description = describe_model(path)
    assert description.algorithm == "MaskablePPO" and description.action_space.n == 3600
    shapes = {k: s.shape for k, s in description.observation_space.spaces.items()}
    assert shapes == {"free": (3600,), "known": (3600,), "state": (6,)}
