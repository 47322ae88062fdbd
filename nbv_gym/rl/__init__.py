"""Reinforcement learning on ``Explore-v0`` with stable-baselines3 (the ``rl`` extra).

- :class:`~nbv_gym.rl.config.TrainConfig`, :func:`~nbv_gym.rl.config.load_train_config`: the
  training config (the shipped ``ppo``, ``nbv_gym/configs/train/ppo.toml``).
- :func:`~nbv_gym.rl.train.train`: train into a run folder, or resume from a checkpoint.
- :class:`~nbv_gym.rl.agent.SB3Policy`: a saved model as a policy (``load_policy("sb3:PATH")``).
- :class:`~nbv_gym.rl.vecenv.LeanSubprocVecEnv`, :class:`~nbv_gym.rl.daskvec.DaskVecEnv`: the
  training environments in local worker processes, or on a Dask cluster's workers.
- :mod:`~nbv_gym.rl.extractor`: the CNN feature extractor and the goal-map policies.
- :func:`~nbv_gym.rl.recipe.run_recipe`: a staged recipe (a config with ``[imitation]``, the
  shipped ``imitation-time``): DAgger labels of a teacher (:mod:`~nbv_gym.rl.labels`, shards
  :mod:`~nbv_gym.rl.labelfile`), imitation (:mod:`~nbv_gym.rl.imitation`), then RL.

Only the config imports without torch; the rest needs the ``rl`` extra (the CPU build of PyTorch first:
:data:`nbv_gym.core.errors.CPU_TORCH`, then ``pip install "nbv-gym[rl]"``). Nothing is
imported here, so that ``nbv-gym --help`` stays instant.
"""
