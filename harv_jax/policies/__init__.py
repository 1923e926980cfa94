"""Policies shipped as package data (``<file>.npz``, model card ``MODEL_CARD.md``); names only, no jax.

``teacher`` (the product of ``harv-jax train --seed 41``: the default preset, taught by the braking SMC)
is the default of ``--policy``; ``fast`` (our reward with energy braking, best of 13 tuning seeds) and
``recovery`` (our reward without braking) stay selectable; the paper's policies keep names that say so
(``paper-full``, ``paper-partial``; the older ``full``/``partial`` are still accepted).
"""

#: Shipped policy name -> file stem.
SHIPPED: dict[str, str] = {
    "teacher": "teacher",
    "fast": "fast",
    "recovery": "recovery",
    "paper-full": "full",
    "paper-partial": "partial",
    "full": "full",
    "partial": "partial",
}
#: The shipped policy that ``--policy`` defaults to.
DEFAULT_SHIPPED = "teacher"
SHIPPED_PREFIX = "shipped"
#: The default ``--policy`` spec, as written in outputs.
DEFAULT_POLICY_SPEC = f"{SHIPPED_PREFIX}:{DEFAULT_SHIPPED}"
