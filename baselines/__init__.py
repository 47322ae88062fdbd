"""Reference policies of nbv-gym: the frontier baselines and the statistic-based NBV policies."""
