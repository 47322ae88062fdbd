"""Probes of the fourth round's scoring, effort and budget classes, as a hostile user tried them
(their ids: T, E, R, C): edited scorecards (C01-C14), effort values past their range (T10-T25,
R01, R02, E02, E04), a time budget that leaves no goal (T12-T14, R05, E09, E20), a peer that is
not a Dask scheduler (C26, C31, C34). Each exits 2 with one line naming the problem, or does the
right thing (a clean run of 0 steps), and writes nothing it should not. The classes' own tests
live beside their code (tests/benchmark/test_runchecks.py, tests/core/test_effort_ranges.py, …).
"""

from __future__ import annotations

import json
import math
import socket
import threading
import time
from pathlib import Path

import pytest

from tests.helpers import invoke
from tests.test_probes import TINY, one_line


@pytest.fixture
def here(tmp_path, monkeypatch) -> Path:
    """An empty working folder holding tiny.toml (the probes' 4-cuboid world)."""
    (tmp_path / "tiny.toml").write_text(TINY)
    monkeypatch.chdir(tmp_path)
    return tmp_path


# -- Scorecards that disagree with themselves (C01-C14) -------------------------------------------


def _cheat(folder: Path, edit, recompute: bool = False) -> Path:
    """The shipped standard closest-frontier reference renamed "cheat" with ``edit`` applied
    (the aggregates recomputed from the edited runs when ``recompute``), in ``folder``."""
    from nbv_gym.benchmark.references import reference_path
    from nbv_gym.benchmark.scorecard import card_aggregates

    card = json.loads(reference_path("closest-frontier").read_text())
    card["policy"]["name"] = "cheat"
    edit(card)
    if recompute:
        card["aggregates"] = card_aggregates(card["runs"], card["suite"]["parts"])
    (folder / "cheat").mkdir()
    (folder / "cheat" / "scorecard.json").write_text(json.dumps(card))
    return folder / "cheat"


def _time_runs(card):
    return [run for run in card["runs"] if run["task"] == "time"]


def _double_area(card):
    for run in _time_runs(card):
        run["q_time_auc"] = min(1.0, 2 * run["q_time_auc"])


def test_a_doubled_area_under_q_t_ranked_first_is_refused_c01(here):
    cheat = _cheat(here, _double_area, recompute=True)  # self-consistent at the aggregate level
    line = one_line(invoke("leaderboard", cheat, "--references", "--out", "board"))
    assert "runs[0] (split time-test, world test-00, noise 0, repeat 0): q_time_auc is" in line
    assert "but its own Q(t) samples bound it to" in line and not (here / "board").exists()


#: The probes' other edits (applied to every run, or every time run) and the refusal's words; the
#: aggregates are left as they were, as the run check refuses before they are recomputed.
EDITS = {
    "C08 elapsed 1 s": (lambda c: [r.update(elapsed_s=1.0) for r in c["runs"]], "elapsed_s is 1 s"),
    "C09 elapsed 5000 s": (
        lambda c: [r.update(elapsed_s=5000.0) for r in _time_runs(c)],
        "elapsed_s is 5000 s",
    ),
    "C10 no scans": (lambda c: [r.update(steps=0) for r in c["runs"]], "steps 0 × 10 s"),
    "C16 no path": (
        lambda c: [r.update(path_length_m=0.0) for r in c["runs"]],
        "path_length_m 0 m / 1 m/s",
    ),
    "C12 curves at 0.9": (
        lambda c: [r.update(q_time=[0.9] * 21, q_path=[0.9] * 19) for r in c["runs"]],
        "q_time[20] (at 600 s, past the run's end at",
    ),
    "C03 area removed": (
        lambda c: [r.pop("q_time_auc") for r in c["runs"]],
        "'q_time_auc' is a required property",
    ),
    "C04 area removed from one run": (
        lambda c: _time_runs(c)[0].pop("q_time_auc"),
        "at runs[0]: 'q_time_auc' is a required property",
    ),
    "C05 elapsed removed": (
        lambda c: [r.pop("elapsed_s") for r in c["runs"]],
        "'elapsed_s' is a required property",
    ),
    "C11 a 1-point Q(t)": (
        lambda c: [r.update(q_time=r["q_time"][:1]) for r in c["runs"]],
        "q_time: holds 1 values, at least 21 expected",
    ),
    "C14 protocol version 3": (
        lambda c: c.update(protocol_version=3),
        "protocol version 3 is newer than this nbv-gym's (2)",
    ),
}


@pytest.mark.parametrize("case", EDITS)
def test_an_edited_scorecard_is_one_line_naming_the_run_and_field(here, case):
    edit, words = EDITS[case]
    cheat = _cheat(here, edit)
    for references in ([], ["--references"]):  # ranked alone (C14) or with the references
        line = one_line(invoke("leaderboard", cheat, *references, "--out", "board"))
        assert words in line, line
    assert not (here / "board").exists()


# -- Effort values past their range (T10-T25, R01, R02, E02, E04) ----------------------------------

SWEEP_TIME = """
worlds = ["tiny.toml"]
policies = ["closest-frontier"]
noise = [0]
repeats = 1
task = "time"
[env.simulator.episode]
{episode}
"""
TRAIN = """
algorithm = "MaskablePPO"
total_timesteps = 32
n_envs = 1
train_worlds = ["tiny.toml"]
eval_worlds = ["tiny.toml"]
task = "time"
{extra}
[learning]
n_steps = 32
batch_size = 32
n_epochs = 1
"""
RUN_TIME = ["run", "--world", "tiny.toml", "--no-animation", "--task", "time", "--out", "r"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--speed-mps", "1e308", "--scan-time-s", "0"], "'--speed-mps': expected a finite number"),
        (["--time-budget-s", "1e308"], "'--time-budget-s': expected a finite number ≥ 1 and ≤"),
        (["--scan-time-s", "5000"], "'--scan-time-s': expected a finite number ≥ 0 and ≤ 3600"),
        (["--speed-mps", "0.001"], "≥ 0.01 and ≤ 100, got 0.001"),
    ],
    ids=["T11-speed", "T15-budget", "scan", "crawl"],
)
def test_effort_options_past_their_range_are_one_line(here, args, message):
    assert message in one_line(invoke(*RUN_TIME, *args))
    assert not (here / "r").exists()


@pytest.mark.parametrize(
    ("kind", "text", "message"),
    [
        ("sweep", SWEEP_TIME.replace("[env.simulator.episode]\n", "").format(
            episode="speed_mps = inf\nscan_time_s = 0.0"),
         "speed_mps: must be from 0.01 to 100 m/s, got inf"),
        ("train", TRAIN.format(extra="time_budget_s = inf"),
         "time_budget_s: must be from 1 to 86,400 s, got inf"),
        ("train", TRAIN.format(extra="speed_mps = inf\nscan_time_s = 0.0"),
         "speed_mps: must be from 0.01 to 100 m/s, got inf"),
    ],
    ids=["T25-sweep", "R01-train-budget", "R02-train-speed"],
)  # fmt: skip
def test_effort_values_past_their_range_in_configs_are_one_line_and_write_nothing(
    here, kind, text, message
):
    (here / "c.toml").write_text(text)
    args = ["sweep", "c.toml"] if kind == "sweep" else ["train", "--config", "c.toml"]
    assert message in one_line(invoke(*args, "--out", "o"))
    assert not (here / "o").exists()  # R07: no partial folder to refuse a corrected rerun


@pytest.mark.parametrize(
    ("keywords", "message"),
    [
        ({"speed_mps": math.inf, "scan_time_s": 0.0}, "speed_mps: must be from 0.01 to 100 m/s"),
        ({"time_budget_s": math.inf}, "time_budget_s: must be from 1 to 86,400 s, got inf"),
        ({"time_budget_s": 1e308}, "time_budget_s: must be from 1 to 86,400 s"),
        ({"scan_time_s": math.nan}, "scan_time_s: must be from 0 to 3,600 s, got nan"),
    ],
    ids=["E02", "E04", "huge-budget", "nan-scan"],
)
def test_effort_keywords_of_gymnasium_make_are_config_errors(here, keywords, message):
    import gymnasium

    from nbv_gym.core.errors import ConfigError

    with pytest.raises(ConfigError, match=message):
        gymnasium.make("nbv_gym/ExploreTime-v0", world="tiny.toml", **keywords)


def test_a_subnormal_scan_time_is_a_free_scan_t10(here):
    """Within the range, 5e-324 s is a scan all but free: the run goes on as with 0 s."""
    result = invoke(*RUN_TIME, "--scan-time-s", "5e-324", "--time-budget-s", "20", "--json")
    assert result.code == 0, result.err
    summary = json.loads(result.out)
    assert summary["n_steps"] >= 1 and summary["final"]["elapsed_s"] <= 20


# -- A time budget that leaves no goal (T12-T14, R05) ----------------------------------------------


@pytest.mark.parametrize(
    ("budget", "policy"),
    [("5", "closest-frontier"), ("11", "closest-frontier"), ("5", "ig-unknown")],
    ids=["T12", "T13", "T14"],
)
def test_a_budget_that_leaves_no_goal_is_a_run_of_0_steps_naming_it(here, budget, policy):
    result = invoke(*RUN_TIME, "--time-budget-s", budget, "--policy", policy, "--json")
    assert result.code == 0 and "Traceback" not in result.err, result.err
    summary = json.loads(result.out)
    assert summary["n_steps"] == 0
    reason = summary["end_reason"]
    assert f"time budget spent at the first scan: time_budget_s = {budget} s leaves no goal" in (
        reason
    )
    assert (here / "r" / "summary.json").is_file()


def test_a_training_whose_budget_leaves_no_goal_is_refused_r05(here):
    (here / "c.toml").write_text(TRAIN.format(extra="time_budget_s = 5.0"))
    line = one_line(invoke("train", "--config", "c.toml", "--out", "o"))
    assert "time_budget_s: 5 s leaves no goal: each costs a scan (scan_time_s = 10 s)" in line
    assert not (here / "o").exists()


# -- A peer that is not a Dask scheduler (C26, C31, C34) -------------------------------------------


class _Peer:
    """A TCP listener on 127.0.0.1 (a free port) that accepts and says nothing, or answers every
    connection with ``answer``; it holds its connections until closed."""

    def __init__(self, answer: bytes = b""):
        self.socket = socket.create_server(("127.0.0.1", 0))
        self.socket.settimeout(0.2)
        self.address = f"tcp://127.0.0.1:{self.socket.getsockname()[1]}"
        self.answer, self.held, self.open = answer, [], True
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while self.open:
            try:
                connection, _ = self.socket.accept()
            except OSError:
                continue
            self.held.append(connection)
            if self.answer:
                connection.sendall(self.answer)

    def close(self) -> None:
        self.open = False
        self.thread.join(5)
        for connection in self.held:
            connection.close()
        self.socket.close()


@pytest.mark.parametrize(
    ("answer", "message"),
    [
        (b"", "accepted the connection but sent no Dask handshake within 2 s"),
        (b"HTTP/1.0 200 OK\r\n\r\n" + b"x" * 100_000, "answered with something that is not Dask"),
    ],
    ids=["C26-C34-silent", "C31-junk"],
)
def test_score_on_a_peer_that_is_not_a_scheduler_is_one_line_in_bounded_time(
    here, monkeypatch, answer, message
):
    pytest.importorskip("distributed")
    monkeypatch.setattr("nbv_gym.core.cluster.SCHEDULER_TIMEOUT_S", 2.0)
    peer = _Peer(answer)
    try:
        start = time.monotonic()
        result = invoke("score", "closest-frontier", "--suite", "quick", "--workers", "1",
                        "--out", "s", "--scheduler", peer.address)  # fmt: skip
        waited = time.monotonic() - start
    finally:
        peer.close()
    assert message in one_line(result)
    assert waited < 2.0 + 2 * 5.0 + 20.0  # the timeout, its grace, the imports
    assert not (here / "s").exists()  # refused before the folder is made
