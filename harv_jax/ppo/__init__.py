"""PPO for the recovery env, in Brax's style on current jax: networks, losses, trainer, checkpoints.

Import the pieces from their modules (``harv_jax.ppo.train.make_train``, ``harv_jax.ppo.config.PPOConfig``,
``harv_jax.ppo.losses.compute_gae`` ...); this package does not import jax-heavy modules eagerly.
"""
