"""A stored reference run gives the same bits of every figure whatever kernels the CPU selects.

numpy, OpenBLAS, numba (LLVM) and the C library each choose code by CPU: numpy's AVX-512 and
AVX2 loops of its transcendental functions, OpenBLAS's core type, numba's target, glibc's FMA
variants of ``exp``/``log``/``sin``/``cos``. The reference scorecards were made on one CPU and
must reproduce on a reviewer's. Here the stored run is re-run in subprocesses that force the
other choices — the ones a CPU without AVX-512, or without AVX2 and FMA, makes — with its world
built afresh in each, and every figure must equal the stored one bit for bit.

An AVX-512 CPU's own loops cannot be forced on a CPU without them, so the first subprocess also
stands in for one: it runs the stored run with every numpy function that has CPU-dependent
loops (``numpy.lib.introspect.opt_func_info``) and is not exact arithmetic made to refuse float
arguments, as well as the BLAS products, and names the call that tried one.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from nbv_gym.benchmark.references import REFERENCE_SUITE, load_references
from nbv_gym.benchmark.rerun import run_difference

ROOT = Path(__file__).resolve().parents[2]  # the subprocess imports tests.helpers from here
#: The stored run re-run: (policy, split, world, noise, repeat). A run whose Q curves moved on an
#: AVX-512 CPU before numpy's loops were taken off the path.
RUN = ("closest-frontier", "benchmark", "pp1-cuboids", 0, 0)

#: numpy's dispatched functions whose loops give the same bits on every CPU (exact IEEE
#: arithmetic, comparisons, selections); every other float function with CPU-dependent loops is
#: refused in the guarded run.
EXACT = {
    "absolute", "add", "argmax", "argmin", "ceil", "copysign", "divide", "equal", "floor",
    "fmax", "fmin", "frexp", "greater", "greater_equal", "isfinite", "isinf", "isnan", "ldexp",
    "less", "less_equal", "maximum", "minimum", "multiply", "negative", "not_equal", "positive",
    "reciprocal", "rint", "sign", "signbit", "sqrt", "square", "subtract", "trunc",
}  # fmt: skip

#: Re-runs RUN (argv: the run, "guard" or not, the exact functions) and prints its figures as a
#: scorecard stores them (JSON floats round-trip exactly).
SCRIPT = """
import json, sys
import numpy as np
from nbv_gym.benchmark.references import REFERENCE_SUITE
from nbv_gym.benchmark.suiterun import part_config, run_figures
from nbv_gym.core.config import to_dict
from nbv_gym.sweep.worker import RunTask, _run

name, split, world, noise, repeat = json.loads(sys.argv[1])
part = REFERENCE_SUITE.part(split)
config = part_config(REFERENCE_SUITE, part, name, {w: w for w in part.world_names})
spec = next(s for s in config.runs() if (s.world, s.noise, s.repeat) == (world, noise, repeat))
task = RunTask(spec, to_dict(config.env_config(world, noise)))

if sys.argv[2] == "guard":
    import traceback
    from numpy.lib.introspect import opt_func_info
    import pathlib, tempfile
    from tests.helpers import write_tiny_world
    exact = set(json.loads(sys.argv[3]))
    # compile every kernel first, on another world (numba reads numpy's functions when it
    # compiles): the stored run's world is then built under the guard
    tiny = str(write_tiny_world(pathlib.Path(tempfile.mkdtemp())))
    simulator = {**task.env["simulator"], "world": tiny}
    simulator["episode"] = {**simulator["episode"], "max_steps": 2}
    _run(RunTask(spec, {**task.env, "simulator": simulator}), None)
    dispatched = {n for n, loops in opt_func_info(signature="float64|float32").items()
                  if any(l["available"] != "baseline(X86_V2)" for l in loops.values())}
    refused = sorted(dispatched - exact) + ["dot", "vdot", "inner", "matmul"]
    def refusing(name, f):
        def call(*args, **kwargs):
            if any(np.asarray(a).dtype.kind in "fc" for a in args if not callable(a)):
                where = [f"{s.filename}:{s.lineno}" for s in traceback.extract_stack()[:-1]
                         if "/numpy/" not in s.filename][-3:]
                raise RuntimeError(f"np.{name} (CPU-dependent loops) called at {where}")
            return f(*args, **kwargs)
        return call
    for n in refused:
        setattr(np, n, refusing(n, getattr(np, n)))
    norm, vector_norm = np.linalg.norm, refusing("linalg.norm", np.linalg.norm)
    def rows_norm(x, ord=None, axis=None, keepdims=False):  # along an axis: exact arithmetic
        return (norm if axis is not None else vector_norm)(x, ord, axis, keepdims)
    np.linalg.norm = rows_norm  # without an axis, a BLAS dot

from nbv_gym.benchmark.scorecard import dumps_strict
print(dumps_strict(run_figures(part, _run(task, None))))
"""

#: What each subprocess forces: a CPU without AVX-512 (numpy's X86_V4 loops off; OpenBLAS's
#: Haswell kernel), guarded; and a CPU without AVX2 or FMA (numpy's X86_V3 loops off, OpenBLAS's
#: Prescott kernel, numba compiling for a generic x86-64, glibc's SSE2 variants).
CPUS = {
    "no AVX-512, guarded": {
        "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
        "OPENBLAS_CORETYPE": "Haswell",
    },
    "no AVX2 and no FMA": {
        "NPY_DISABLE_CPU_FEATURES": "X86_V3 X86_V4 AVX512_ICL AVX512_SPR",
        "OPENBLAS_CORETYPE": "Prescott",
        "NUMBA_CPU_NAME": "generic",
        "GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA,-AVX,-FMA4",
    },
}


def _rerun(env: dict[str, str], cache, guard: bool) -> dict:
    environment = {**os.environ, **env, "NBV_GYM_CACHE": str(cache)}
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT, json.dumps(RUN), "guard" if guard else "plain",
         json.dumps(sorted(EXACT))],
        capture_output=True, text=True, env=environment, timeout=900, cwd=ROOT,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout)


def _stored() -> dict:
    name, split, world, noise, repeat = RUN
    card = next(c for c in load_references(REFERENCE_SUITE.name) if c["policy"]["name"] == name)
    run = next(
        r
        for r in card["runs"]
        if (r["split"], r["world"], r["noise"], r["repeat"]) == (split, world, noise, repeat)
    )
    return run


@pytest.mark.slow
@pytest.mark.parametrize("cpu", CPUS)
def test_a_stored_run_gives_the_same_bits_on_another_cpu(cpu, tmp_path):
    now = _rerun(CPUS[cpu], tmp_path / "cache", guard="guarded" in cpu)
    moved = run_difference(_stored(), now)
    assert moved is None, f"under {cpu} the stored run gives other figures ({moved})"
