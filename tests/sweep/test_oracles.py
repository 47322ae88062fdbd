"""A sweep fails the runs of a policy that reads ground truth, naming the key, and its report
marks an oracle policy and ranks it apart."""

from __future__ import annotations

import json

import pandas as pd

from nbv_gym.sweep.config import load_sweep_config
from nbv_gym.sweep.folder import ResultStore
from nbv_gym.sweep.report import build_report
from nbv_gym.sweep.runner import run_sweep


def test_a_sweep_fails_peeking_runs_and_marks_the_oracle_in_its_report(
    peeking_policies, tmp_path, make_config
):
    policies = ["closest-frontier", "peeking:Oracle", "peeking:PeekWorld", "peeking:PeekPose"]
    config = make_config(tmp_path, policies=policies, retries=0, max_steps=3)
    out = tmp_path / "out"
    run_sweep(load_sweep_config(config), out, workers=2, progress=False,
              python_path=(str(peeking_policies),))  # fmt: skip
    runs = pd.read_csv(out / "runs.csv").set_index("policy")
    assert runs.loc["peeking:Oracle", "status"] == "ok" and runs.loc["peeking:Oracle", "oracle"]
    assert runs.loc["closest-frontier", "status"] == "ok"
    assert not runs.loc["closest-frontier", "oracle"]
    for name, key in (("peeking:PeekWorld", "world"), ("peeking:PeekPose", "true_pose")):
        assert runs.loc[name, "status"] == "failed"
        assert f"PrivilegedInfoError: Policy {name} read info['{key}']" in runs.loc[name, "error"]
    report = build_report(out).read_text()
    final = report.split("## Final quality")[1].split("###")[0]
    assert "peeking:Oracle (oracle)" in final
    rows = [line for line in final.splitlines() if line.startswith("| ")]
    names = [row.split("|")[1].strip() for row in rows[1:]]  # after the header
    assert names.index("closest-frontier") < names.index("peeking:Oracle (oracle)")
    assert any(name.startswith("*oracles") for name in names)  # the rule between them
    assert "peeking:Oracle (oracle)" in report.split("## Comparison at equal scans, travel free")[1]
    # A run record of an older version (no "oracle" column) still counts as finished.
    (path,) = (out / "runs").glob("*closest-frontier*.json")
    record = json.loads(path.read_text())
    del record["run"]["oracle"]
    path.write_text(json.dumps(record))
    ResultStore(out).consolidate()
    again = pd.read_csv(out / "runs.csv").set_index("policy")
    assert again.loc["closest-frontier", "status"] == "ok" and not (out / "corrupt").exists()
