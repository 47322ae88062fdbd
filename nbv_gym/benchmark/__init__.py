"""The benchmark: fixed evaluation suites, scorecards and the leaderboard.

- :mod:`nbv_gym.benchmark.suites`: the suites ``standard`` and ``quick`` (data), the protocol
  version, the suites' content hash and the one table of the splits' and scores' labels.
- :mod:`nbv_gym.benchmark.testsplit`: the generated test worlds, held out from the benchmark and
  the training pools.
- :mod:`nbv_gym.benchmark.suiterun`: one policy run through a suite, :func:`score_policy`
  (``nbv-gym score``), on the sweep's resumable runner; it writes the scorecard.
- :mod:`nbv_gym.benchmark.curves`: a run's Q against elapsed time and path length (step
  functions), the grids a scorecard keeps them on and the area under Q(t).
- :mod:`nbv_gym.benchmark.scorecard`: the scorecard (fields, aggregates, strict JSON, schema);
  :mod:`nbv_gym.benchmark.cardtypes`: its shape as TypedDicts, key for key the schema's.
- :mod:`nbv_gym.benchmark.references`: the shipped policies' reference scorecards and how to
  regenerate them.
- :mod:`nbv_gym.benchmark.ranking`: one scorecard on a leaderboard, the order a board ranks
  them in (oracles apart), the baseline and ``P(better)`` against it, the Pareto front.
- :mod:`nbv_gym.benchmark.leaderboard`: ``nbv-gym leaderboard``: ranked by the time task, the
  Pareto front of (Q, path), Q(t) and performance profiles.
"""
