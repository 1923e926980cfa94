"""Policies shipped as package data (``<file>.npz``, model card ``MODEL_CARD.md``); names only, no jax.

``fast`` (our reward with energy braking: it recovers on its own, faster than the SMC on upsets) is the
default of ``--policy``; ``recovery`` (our reward without braking) stays selectable; the paper's policies keep
names that say so (``paper-full``, ``paper-partial``; the older ``full``/``partial`` are still
accepted).
"""

#: Shipped policy name -> file stem.
SHIPPED: dict[str, str] = {"fast": "fast", "recovery": "recovery", "paper-full": "full",
                           "paper-partial": "partial", "full": "full", "partial": "partial"}  # fmt: skip
#: The shipped policy that ``--policy`` defaults to.
DEFAULT_SHIPPED = "fast"
SHIPPED_PREFIX = "shipped"
#: The default ``--policy`` spec, as written in outputs.
DEFAULT_POLICY_SPEC = f"{SHIPPED_PREFIX}:{DEFAULT_SHIPPED}"
