"""Generic PPO in Brax's manner on current jax: it knows gymnax-style envs, nothing of the aircraft or task.

Modules: ``config`` (PPOConfig, validation, a generic TOML loader), ``networks``, ``losses``, ``normalize``,
``demos`` (demonstration pairs cloned in the update), ``train`` (the compiled training step: ``make_train``),
``train_state`` (its types: ``TrainingState``, ``Trainer``), ``acting`` (the env interface,
episode metrics, ``make_evaluate``), ``runner`` (the host driver: periods, checkpoints, logging, resume,
``run_training``), ``sharding`` (device mesh and placement), ``checkpoint``, ``watchdog``. Task metrics come
in only through ``episode_metrics_fn``; the HARV recipe that uses this is ``harv_jax.training``. Import the
pieces from their modules; this package does not import jax-heavy modules eagerly.
"""
