"""Policies shipped as package data (``<file>.npz``, model card ``MODEL_CARD.md``); names only, no jax.

``recovery`` (our reward, spin resets: it recovers on its own) is the default of ``--policy``; the paper's
policies keep names that say so (``paper-full``, ``paper-partial``; the older ``full``/``partial`` are still
accepted).
"""

#: Shipped policy name -> file stem.
SHIPPED: dict[str, str] = {"recovery": "recovery", "paper-full": "full", "paper-partial": "partial",
                           "full": "full", "partial": "partial"}  # fmt: skip
#: The shipped policy that ``--policy`` defaults to.
DEFAULT_SHIPPED = "recovery"
SHIPPED_PREFIX = "shipped"
#: The default ``--policy`` spec, as written in outputs.
DEFAULT_POLICY_SPEC = f"{SHIPPED_PREFIX}:{DEFAULT_SHIPPED}"
