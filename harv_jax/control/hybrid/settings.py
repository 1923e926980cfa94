"""The hybrid's settings: its traced gains, the names of its zeta schedules and the default schedule.

Read by the hybrid (``harv_jax.control.hybrid.law``), its zeta schedules
(``harv_jax.control.hybrid.schedules``) and the controller registry, none of which imports another for them.
"""

from __future__ import annotations

from typing import Literal

import jax.numpy as jnp
from flax import struct

from harv_jax.control.hybrid.gate import GateGains
from harv_jax.control.hybrid.supervisor import SupervisorGains
from harv_jax.control.hybrid.zeta import SimplexGains
from harv_jax.control.smc import SMCGains

ZetaScheduleName = Literal["hysteresis", "continuous", "gated", "simplex", "always", "never"]
ZETA_SCHEDULES: tuple[str, ...] = ("hysteresis", "continuous", "gated", "simplex", "always", "never")

#: The hybrid's default zeta schedule: the policy alone until a monitor hands over to the SMC for good
#: (``control.hybrid.zeta.simplex_step``; ``experiments/hybrid_simplex/README.md``).
DEFAULT_ZETA = "simplex"


@struct.dataclass
class HybridGains:
    """Traced settings of the hybrid controller (sweep them without recompiling).

    Attributes:
        smc: the SMC gains of the feedback term.
        e_on_rad: [3] outer tube radii: zeta -> 1 when any |e_i| exceeds its radius, rad.
        e_off_rad: [3] inner tube radii: zeta -> 0 when all |e_i| are below theirs, rad.
        zeta_min_dwell_s: minimum time between two hysteresis switches, s.
        zeta_floor: lower bound of zeta for the hysteresis and continuous schedules, in [0, 1]:
            zeta = floor + (1 - floor) zeta_schedule. The paper's stability analysis assumes zeta in
            (0, 1]; its tube sets zeta = 0 inside (floor 0). Default ``DEFAULT_ZETA_FLOOR``.
        authority_frac: [3] cap of |u_RL| as a fraction of each channel's limits, in (0, 1].
        gate: GateGains of the ``gated`` schedule (``harv_jax.control.hybrid.gate``; every schedule logs its
            certificate).
        supervisor: SupervisorGains.
        simplex: SimplexGains of the ``simplex`` schedule.
    """

    smc: SMCGains
    e_on_rad: jnp.ndarray
    e_off_rad: jnp.ndarray
    zeta_min_dwell_s: jnp.ndarray
    zeta_floor: jnp.ndarray
    authority_frac: jnp.ndarray
    gate: GateGains
    supervisor: SupervisorGains
    simplex: SimplexGains
