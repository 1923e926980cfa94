"""1976 US standard atmosphere (troposphere + lower stratosphere), h as geopotential altitude."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from harv_jax.units import M_PER_FT

RHO_SL_SLUGFT3 = 0.0023769  # sea-level density, slug/ft^3
T0_K = 288.15  # sea-level temperature, K
LAPSE_KPM = 0.0065  # tropospheric lapse rate, K/m
G0_MPS2 = 9.80665
R_JPKGK = 8.31432 / 0.0289644  # specific gas constant of air, J/(kg K)
N_EXP = G0_MPS2 / (R_JPKGK * LAPSE_KPM)  # ~5.255876
H_TROPOPAUSE_M = 11000.0
T11_K = 216.65
THETA11 = T11_K / T0_K


def log_density_ratio(h_ft: jnp.ndarray) -> jnp.ndarray:
    """ln(rho / rho_SL) at altitude h_ft: one log (troposphere) or a linear form (stratosphere).

    The density and the thrust lapse (rho/rho_SL)^0.7 both follow from it with one exp each
    (3 transcendentals instead of 5 for two powers and the stratosphere's exp).
    """
    h_m = h_ft * M_PER_FT
    theta = (T0_K - LAPSE_KPM * jnp.minimum(h_m, H_TROPOPAUSE_M)) / T0_K
    tropo = (N_EXP - 1.0) * jnp.log(theta)
    strato = (N_EXP - 1.0) * float(np.log(THETA11)) - G0_MPS2 * (
        jnp.maximum(h_m, H_TROPOPAUSE_M) - H_TROPOPAUSE_M
    ) / (R_JPKGK * T11_K)
    return jnp.where(h_m < H_TROPOPAUSE_M, tropo, strato)


def density_slugft3(h_ft: jnp.ndarray) -> jnp.ndarray:
    """Air density, slug/ft^3, at altitude h_ft (rho(25,000 ft) = 1.06513e-3)."""
    return RHO_SL_SLUGFT3 * jnp.exp(log_density_ratio(h_ft))


def density_and_thrust_lapse(h_ft: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
    """(rho slug/ft^3, (rho/rho_SL)^0.7) at altitude h_ft, from one ``log_density_ratio``."""
    lr = log_density_ratio(h_ft)
    return RHO_SL_SLUGFT3 * jnp.exp(lr), jnp.exp(0.7 * lr)


def thrust_lbf(throttle: jnp.ndarray, T_max_lbf: jnp.ndarray, h_ft: jnp.ndarray) -> jnp.ndarray:
    """Thrust along body +x: T = throttle * T_max * (rho/rho_SL)^0.7, lbf."""
    return throttle * T_max_lbf * density_and_thrust_lapse(h_ft)[1]
