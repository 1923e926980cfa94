"""Episode-end metrics of the recovery env, handed to the generic trainer as its ``episode_metrics_fn``.

[`harv_episode_metrics`][] reads one env's ``info`` at the step an episode ends (``final_state_wind``,
the wind-axis state [10], and ``final_obs``, the observation [11] holding the targets) by component name,
and returns the scalars that ``harv_jax.ppo`` averages over the episodes of a period (``episode/<name>``).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from harv_jax.dynamics.state import WIND_INDEX
from harv_jax.task.spaces import OBS_NAMES
from harv_jax.task.spec import RECOVERY_ALPHA_TOL_RAD as ALPHA_TOL_RAD
from harv_jax.task.spec import RECOVERY_BETA_TOL_RAD as BETA_TOL_RAD
from harv_jax.task.spec import RECOVERY_MU_TOL_RAD as MU_TOL_RAD
from harv_jax.task.spec import RECOVERY_OMEGA_TOL_RADPS as OMEGA_TOL_RADPS

#: The recovery tolerances of the training-time metric are the criterion's (``task.spec``), instantaneous.

_OBS_INDEX = {n: i for i, n in enumerate(OBS_NAMES)}
_I_ALPHA, _I_BETA, _I_MU = WIND_INDEX["alpha"], WIND_INDEX["beta"], WIND_INDEX["mu"]
_I_ALPHA_D, _I_BETA_D, _I_MU_D = _OBS_INDEX["alpha_d"], _OBS_INDEX["beta_d"], _OBS_INDEX["mu_d"]
#: The body rates (p, q, r) as one slice of the wind state (they are stored next to each other).
_RATES = slice(WIND_INDEX["p"], WIND_INDEX["r"] + 1)
assert [WIND_INDEX[n] for n in ("p", "q", "r")] == list(range(_RATES.start, _RATES.stop))


def harv_episode_metrics(info: dict[str, Any]) -> dict[str, jax.Array]:
    """Episode-end metrics of the HARV recovery env, from one env's ``info`` (scalars).

    ``final_omega_radps``: ||(p, q, r)|| of the state the episode ended in; ``recovered``: 1 if the episode
    was not terminated and its final state meets |e_alpha| < 2 deg, |e_beta| < 1 deg, |e_mu| < 2 deg and
    ||omega|| < 0.17 rad/s (the recovery criterion at the last step only, without the 10 s hold);
    ``alpha_ok``: |e_alpha| < 2 deg at the end, not terminated; ``terminated``: left the envelope;
    ``final_omega_alive_radps`` and ``final_abs_e_alpha_rad``: ||omega|| and |e_alpha| at the end if not
    terminated, else 0 (divide their mean by ``1 - terminated`` for the mean over surviving episodes).
    """
    x = info["final_state_wind"]
    obs = info["final_obs"]
    omega = jnp.sqrt(jnp.sum(jnp.square(x[_RATES])))
    e_alpha = jnp.abs(x[_I_ALPHA] - obs[_I_ALPHA_D])
    e_beta = jnp.abs(x[_I_BETA] - obs[_I_BETA_D])
    e_mu = jnp.abs(jnp.mod(x[_I_MU] - obs[_I_MU_D] + jnp.pi, 2.0 * jnp.pi) - jnp.pi)
    ok = ~info["terminated"]
    alpha_ok = ok & (e_alpha < ALPHA_TOL_RAD)
    recovered = alpha_ok & (e_beta < BETA_TOL_RAD) & (e_mu < MU_TOL_RAD) & (omega < OMEGA_TOL_RADPS)
    f32 = jnp.float32
    return {
        "recovered": recovered.astype(f32),
        "alpha_ok": alpha_ok.astype(f32),
        "final_omega_radps": jnp.where(jnp.isfinite(omega), omega, 0.0).astype(f32),
        "terminated": info["terminated"].astype(f32),
        "final_omega_alive_radps": jnp.where(ok & jnp.isfinite(omega), omega, 0.0).astype(f32),
        "final_abs_e_alpha_rad": jnp.where(ok & jnp.isfinite(e_alpha), e_alpha, 0.0).astype(f32),
    }
