"""The record of a wrapped recovery env: the plain env's interface plus what its wrappers add.

Each wrapper of the training layer (``training.in_loop``: a controller inside the step;
``training.teacher``: a teacher's labels; ``training.measured_env``: the policy's measurement path) returns a
[`WrappedEnv`][]: the functions of ``harv_jax.env.recovery.Env`` over its own states (which nest the inner
env's), the inner env's config, parameters and sizes, and what the wrappers add, carried outward by the
wrappers around them ([`wrap`][]).
"""

from __future__ import annotations

from typing import Any, NamedTuple

#: The fields a wrapper adds, carried outward from an inner wrapper.
ADDED_FIELDS = ("loop", "teacher", "measurement_path", "critic_observation")


class WrappedEnv(NamedTuple):
    """Same interface as ``harv_jax.env.recovery.Env``, and what the wrappers add (absent: the defaults)."""

    config: Any
    reset: Any
    step: Any
    step_no_reset: Any
    default_params: Any
    reset_to: Any
    batch_step: Any
    observation_size: int
    action_size: int
    loop: str = "none"  # the controller inside the step (``hybrid:<schedule>``) or none
    teacher: str | None = None  # the registry name of the controller that labels every step
    measurement_path: dict[str, Any] | None = None  # the policy's measurement path (its record)
    critic_observation: Any = None  # state -> [O] the true state's observation (privileged critic) or None


def wrap(
    env: Any, reset: Any, step: Any, step_no_reset: Any, reset_to: Any, batch_step: Any, **added: Any
) -> WrappedEnv:
    """The record of a wrapper around ``env`` with these functions: ``env``'s config, parameters and sizes,
    what ``env``'s own wrappers added, and ``added`` (this wrapper's fields, among ``ADDED_FIELDS``)."""
    unknown = set(added) - set(ADDED_FIELDS)
    if unknown:
        raise ValueError(f"wrapper fields {sorted(unknown)}; allowed: {', '.join(ADDED_FIELDS)}")
    carried = {k: getattr(env, k) for k in ADDED_FIELDS if hasattr(env, k)}
    return WrappedEnv(
        config=env.config,
        reset=reset,
        step=step,
        step_no_reset=step_no_reset,
        default_params=env.default_params,
        reset_to=reset_to,
        batch_step=batch_step,
        observation_size=env.observation_size,
        action_size=env.action_size,
        **{**carried, **added},
    )
