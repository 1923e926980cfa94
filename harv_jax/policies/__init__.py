"""Policies shipped as package data (``<file>.npz``, model card ``MODEL_CARD.md``); names only, no jax.

``robust`` (the product of ``harv-jax train --seed 4817``: the default preset, taught by the braking SMC in a
disturbed world and flown behind the 2 Hz low-pass it was trained with) is the default of ``--policy``;
``teacher`` (the same recipe in a clean world), ``fast`` (our reward with energy braking, best of 13 tuning
seeds) and ``recovery`` (our reward without braking) stay selectable; the paper's policies keep names that
say so (``paper-full``, ``paper-partial``; the older ``full``/``partial`` are still accepted).
"""

#: Shipped policy name -> file stem.
SHIPPED: dict[str, str] = {
    "robust": "robust",
    "teacher": "teacher",
    "fast": "fast",
    "recovery": "recovery",
    "paper-full": "full",
    "paper-partial": "partial",
    "full": "full",
    "partial": "partial",
}
#: The shipped policy that ``--policy`` defaults to.
DEFAULT_SHIPPED = "robust"
SHIPPED_PREFIX = "shipped"
#: The default ``--policy`` spec, as written in outputs.
DEFAULT_POLICY_SPEC = f"{SHIPPED_PREFIX}:{DEFAULT_SHIPPED}"
