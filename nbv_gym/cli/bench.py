"""``nbv-gym bench``: the speed figures of the perf suites (:mod:`nbv_gym.perf`)."""

from __future__ import annotations

from typing import Annotated

import typer

from nbv_gym.core.jsonfiles import dumps_json


def bench(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    suite: Annotated[list[str] | None, typer.Option(help="Only these suites.")] = None,
) -> None:
    """Measure throughput (world build, scans, …); progress goes to stderr.

    Examples:

    \b
      nbv-gym bench
      nbv-gym bench --json > bench.json
      nbv-gym bench --suite foundation
    """
    from nbv_gym.perf import run_suites

    results = run_suites(suite, lambda message: typer.echo(message, err=True))
    if as_json:
        typer.echo(dumps_json(results))
        return
    for key, value in results.items():
        typer.echo(f"{key:<28} {value:>14,.4g}")
