"""Files read with bounds (:mod:`nbv_gym.core.inputs`): every loader refuses, in one line and
without blocking, a path that is not a regular file (a FIFO, a device, a folder) or that is
larger than its kind's limit — before a byte is read."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from nbv_gym.benchmark.scorecard import load_scorecard
from nbv_gym.core.arrayfiles import read_npy, read_npz
from nbv_gym.core.config import read_text
from nbv_gym.core.errors import NbvGymError
from nbv_gym.core.inputs import MAX_JSON_BYTES, read_input, read_json
from nbv_gym.core.pointclouds import read_points
from nbv_gym.rl.modelfile import read_model_data

#: Every loader of a file a user hands nbv-gym or a folder holds, by the file name it reads.
LOADERS = {
    "scorecard.json": load_scorecard,
    "sweep.toml": lambda path: read_text(path, "Sweep config"),
    "map.npz": read_npz,
    "truth.npy": read_npy,
    "cloud.ply": read_points,
    "cloud.pcd": read_points,
    "cloud.xyz": read_points,
    "model.zip": read_model_data,
    "summary.json": lambda path: read_json(path, "Run summary"),
}


@pytest.fixture
def no_hang():
    """Fail (instead of blocking forever) if the test takes more than 10 s."""

    def alarm(signum, frame):
        raise TimeoutError("the read blocked")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(10)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


@pytest.mark.parametrize("name", LOADERS)
def test_a_fifo_is_refused_without_blocking(tmp_path, no_hang, name):
    path = tmp_path / name
    os.mkfifo(path)
    with pytest.raises(NbvGymError, match="not a regular file \\(a FIFO\\)"):
        LOADERS[name](path)


@pytest.mark.parametrize("name", LOADERS)
def test_a_link_to_an_endless_device_is_refused(tmp_path, no_hang, name):
    path = tmp_path / name
    path.symlink_to("/dev/zero")
    with pytest.raises(NbvGymError, match="not a regular file \\(a character device\\)"):
        LOADERS[name](path)


@pytest.mark.parametrize("name", [n for n in LOADERS if n.endswith((".json", ".toml"))])
def test_a_file_over_its_limit_is_refused_before_it_is_read(tmp_path, name):
    path = tmp_path / name
    with open(path, "wb") as file:
        file.truncate(MAX_JSON_BYTES + 1)  # sparse: no disk, and never read
    with pytest.raises(NbvGymError, match=f"has {MAX_JSON_BYTES + 1:,} bytes, more than the limit"):
        LOADERS[name](path)


def test_a_file_that_grows_past_its_limit_while_read_is_refused(tmp_path):
    path = tmp_path / "grows"
    path.write_bytes(b"x" * 100)
    assert read_input(path, "File", 100) == b"x" * 100
    with pytest.raises(NbvGymError, match="more than the limit of 99 bytes"):
        read_input(path, "File", 99)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('{"q": NaN}', "NaN is not JSON"),
        ('{"q": Infinity}', "Infinity is not JSON"),
        ('{"q": -Infinity}', "-Infinity is not JSON"),
        ('{"q": 1, "q": 2}', "the key 'q' appears twice"),
        ("[1, 2", "not valid JSON"),
    ],
)
def test_json_that_other_parsers_would_read_otherwise_is_refused(tmp_path, text, message):
    path = tmp_path / "summary.json"
    path.write_text(text)
    with pytest.raises(NbvGymError, match=message):
        read_json(path, "Run summary")


def test_a_missing_file_and_a_folder_are_named(tmp_path):
    with pytest.raises(NbvGymError, match="does not exist"):
        read_json(tmp_path / "missing.json", "Run summary")
    with pytest.raises(NbvGymError, match="is a folder, not a file"):
        read_json(Path(tmp_path), "Run summary")
