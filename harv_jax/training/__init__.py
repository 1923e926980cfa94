"""The HARV training recipe: PPO (``harv_jax.ppo``) on the recovery env (``harv_jax.env``), from a preset.

Modules: ``presets`` (the recipe files shipped in ``presets/*.toml``, looked up by name), ``environment``
(the env and its traced parameters from a preset's env tables), ``start`` (env, trainer and initial policy
of a run; the run folder's ``config.json``), ``demos`` (demonstrations from ``harv-jax optimal``
cloned by the run), ``resume`` (how ``--resume`` continues a run),
``eval_hook`` (evaluation during training), ``outputs`` (metrics CSV, policies, spin bank, summary),
``tensorboard`` (scalars per period), ``stall`` (the watchdog's stall handler), ``run`` (a whole training
run from parsed options).
``harv_jax.commands.train`` parses the command line and calls ``run``.
"""
