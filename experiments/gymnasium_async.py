"""A plain Gymnasium loop over nbv-gym, as CleanRL-style single-file agents run one: parallel
environments from ``gymnasium.make_vec(..., vectorization_mode="async")``, actions drawn among the
valid goals of ``info["action_mask"]`` (int8, one row per environment), Gymnasium's autoreset.
It trains nothing: put a learner where the actions are sampled.

    python experiments/gymnasium_async.py --env-id nbv_gym/ExploreBudget-v0 --world pp1-cuboids

Embree's thread pool does not survive ``fork``: the workers start with ``forkserver``. Learners
that ignore masks pass ``invalid_action="snap"`` instead (the nearest valid goal runs).
"""

from __future__ import annotations

import argparse

import gymnasium
import numpy as np

import nbv_gym  # noqa: F401  (registers the environments)


def make_envs(env_id: str, num_envs: int, **env_kwargs) -> gymnasium.vector.VectorEnv:
    """``num_envs`` environments of ``env_id`` (``env_kwargs`` go to each), one process each."""
    return gymnasium.make_vec(
        env_id,
        num_envs=num_envs,
        vectorization_mode="async",
        vector_kwargs={"context": "forkserver"},
        **env_kwargs,
    )


def sample_valid(space: gymnasium.spaces.Discrete, masks: np.ndarray) -> np.ndarray:
    """One valid goal per environment: ``masks`` (num_envs, n_goals) int8 → (num_envs,) int64."""
    return np.array([space.sample(mask=mask) for mask in masks], dtype=np.int64)


def run(env_id: str, num_envs: int, steps: int, seed: int, **env_kwargs) -> list[dict]:
    """Step ``num_envs`` environments ``steps`` times; the finished episodes' return, length,
    final Q and discovered fraction."""
    envs = make_envs(env_id, num_envs, **env_kwargs)
    envs.single_action_space.seed(seed)
    _, infos = envs.reset(seed=seed)
    returns, lengths, finished = np.zeros(num_envs), np.zeros(num_envs, int), []
    try:
        for _ in range(steps):
            actions = sample_valid(envs.single_action_space, infos["action_mask"])
            _, rewards, terminated, truncated, infos = envs.step(actions)
            returns += rewards
            lengths += 1
            for i in np.flatnonzero(terminated | truncated):
                final = {key: float(infos[key][i]) for key in ("q", "discovered")}
                finished.append({"return": returns[i], "length": int(lengths[i]), **final})
                returns[i], lengths[i] = 0.0, -1  # the next step resets it (autoreset)
    finally:
        envs.close()
    return finished


def main(argv: list[str] | None = None) -> None:
    """Parse the command line and run the comparison (``--help`` lists the options)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-id", default="nbv_gym/ExploreBudget-v0")
    parser.add_argument("--world", default="pp1-cuboids", help="a world name or random:<kind>")
    parser.add_argument("--num-envs", type=int, default=2)
    parser.add_argument("--steps", type=int, default=30, help="vector steps")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--max-steps", type=int, help="the budget (default: the id's)")
    args = parser.parse_args(argv)
    key = "budget_scans" if "Budget" in args.env_id else "max_steps"  # the budget, or truncation
    limit = {} if args.max_steps is None else {key: args.max_steps,
                                                "max_episode_steps": args.max_steps}  # fmt: skip
    episodes = run(args.env_id, args.num_envs, args.steps, args.seed, world=args.world, **limit)
    for k, episode in enumerate(episodes):
        print(
            f"episode {k}: {episode['length']} scans, return {episode['return']:.4f}, "
            f"Q {episode['q']:.4f}, discovered {episode['discovered']:.0%}"
        )
    print(f"{len(episodes)} episodes finished in {args.steps} steps of {args.num_envs} envs")


if __name__ == "__main__":
    main()
