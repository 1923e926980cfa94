"""State definitions and the coordinate change between the two forms of the model.

Wind-axis state (the paper's model; ``derivatives()``), a [10] vector:

| idx | symbol | meaning                                   | unit  |
|-----|--------|-------------------------------------------|-------|
| 0   | V      | true airspeed                             | ft/s  |
| 1   | alpha  | angle of attack                           | rad   |
| 2   | beta   | sideslip angle                            | rad   |
| 3-5 | p,q,r  | body-axis angular rates                   | rad/s |
| 6   | mu     | wind-axis bank angle                      | rad   |
| 7   | gamma  | flight-path angle                         | rad   |
| 8   | chi    | flight-path azimuth                       | rad   |
| 9   | h      | altitude                                  | ft    |

Integration state (singularity-free; ``BodyState``): body velocity (u, v, w) ft/s, body rates
(p, q, r) rad/s, attitude quaternion [q0, q1, q2, q3] (scalar first, body -> NED, unit norm), and
position [x_N ft, y_E ft, h ft] (h positive up). Reference: Stevens, Lewis & Johnson,
*Aircraft Control and Simulation*, 3rd ed., ch. 1-2.

Where the velocity is vertical (gamma = +-90 deg) the split of the attitude between chi and mu is
undefined; ``to_wind`` then returns finite values from the 3-2-1 decomposition of the NED->wind
rotation (mu = atan2(C[1,2], C[2,2]), chi = atan2(v_E, v_N)), which may be arbitrary there.
"""

from __future__ import annotations

import jax.numpy as jnp
from flax import struct

from harv_jax.dynamics.fusion import atan2

#: Names of the wind-axis state components, in order.
WIND_STATE_NAMES: tuple[str, ...] = ("V", "alpha", "beta", "p", "q", "r", "mu", "gamma", "chi", "h")
CONTROL_NAMES: tuple[str, ...] = ("de", "da", "dr")
#: Position of each wind-state component by name (``x[..., WIND_INDEX["alpha"]]``).
WIND_INDEX = {n: i for i, n in enumerate(WIND_STATE_NAMES)}
#: Positions of the tracked outputs [alpha, beta, mu] in the wind state.
TRACKED_INDEX: tuple[int, int, int] = (WIND_INDEX["alpha"], WIND_INDEX["beta"], WIND_INDEX["mu"])
#: The body rates [p, q, r] as a slice of the wind state.
RATES = slice(WIND_INDEX["p"], WIND_INDEX["r"] + 1)


# Named views of a wind-axis state x [..., 10] (any leading axes); use these instead of positions.
def vt_fps(x: jnp.ndarray) -> jnp.ndarray:
    """True airspeed V [...], ft/s."""
    return x[..., WIND_INDEX["V"]]


def alpha_rad(x: jnp.ndarray) -> jnp.ndarray:
    """Angle of attack [...], rad."""
    return x[..., WIND_INDEX["alpha"]]


def beta_rad(x: jnp.ndarray) -> jnp.ndarray:
    """Sideslip [...], rad."""
    return x[..., WIND_INDEX["beta"]]


def omega_radps(x: jnp.ndarray) -> jnp.ndarray:
    """Body rates [p, q, r] [..., 3], rad/s."""
    return x[..., RATES]


def yaw_rate_radps(x: jnp.ndarray) -> jnp.ndarray:
    """Yaw rate r [...], rad/s."""
    return x[..., WIND_INDEX["r"]]


def mu_rad(x: jnp.ndarray) -> jnp.ndarray:
    """Wind-axis bank angle [...], rad."""
    return x[..., WIND_INDEX["mu"]]


def gamma_rad(x: jnp.ndarray) -> jnp.ndarray:
    """Flight-path angle [...], rad."""
    return x[..., WIND_INDEX["gamma"]]


def chi_rad(x: jnp.ndarray) -> jnp.ndarray:
    """Flight-path azimuth [...], rad."""
    return x[..., WIND_INDEX["chi"]]


def h_ft(x: jnp.ndarray) -> jnp.ndarray:
    """Altitude [...], ft."""
    return x[..., WIND_INDEX["h"]]


@struct.dataclass
class BodyState:
    """Singularity-free integration state (see module docstring for units)."""

    uvw_fps: jnp.ndarray  # [3]
    pqr_radps: jnp.ndarray  # [3]
    quat: jnp.ndarray  # [4], scalar first, body -> NED
    pos_ft: jnp.ndarray  # [3] = [x_N, y_E, h]


def airflow_direction(u: jnp.ndarray, v: jnp.ndarray, w: jnp.ndarray) -> tuple[jnp.ndarray, ...]:
    """(sqrt(u^2 + w^2), V, cos alpha, sin alpha, cos beta, sin beta) of a body-axis velocity, ft/s.

    The direction cosines are ratios of the components (no angle, no sine or cosine); at zero speed
    alpha = beta = 0.
    """
    uw2 = u * u + w * w
    uw, vt = jnp.sqrt(uw2), jnp.sqrt(uw2 + v * v)
    uw_safe, vt_safe = jnp.where(uw > 0, uw, 1.0), jnp.where(vt > 0, vt, 1.0)
    ca, sa = jnp.where(uw > 0, u / uw_safe, 1.0), w / uw_safe
    cb, sb = jnp.where(vt > 0, uw / vt_safe, 1.0), v / vt_safe
    return uw, vt, ca, sa, cb, sb


def dcm_wind_from_body(alpha: jnp.ndarray, beta: jnp.ndarray) -> jnp.ndarray:
    """C_wb [3,3]: components in body axes -> components in wind axes."""
    ca, sa, cb, sb = jnp.cos(alpha), jnp.sin(alpha), jnp.cos(beta), jnp.sin(beta)
    zero = jnp.zeros_like(alpha)
    return jnp.array(
        [
            [ca * cb, sb, sa * cb],
            [-ca * sb, cb, -sa * sb],
            [-sa, zero, ca],
        ]
    )


def dcm_321(psi: jnp.ndarray, theta: jnp.ndarray, phi: jnp.ndarray) -> jnp.ndarray:
    """R1(phi) R2(theta) R3(psi) [3,3]: NED components -> rotated-frame components."""
    cps, sps = jnp.cos(psi), jnp.sin(psi)
    cth, sth = jnp.cos(theta), jnp.sin(theta)
    cph, sph = jnp.cos(phi), jnp.sin(phi)
    return jnp.array(
        [
            [cth * cps, cth * sps, -sth],
            [sph * sth * cps - cph * sps, sph * sth * sps + cph * cps, sph * cth],
            [cph * sth * cps + sph * sps, cph * sth * sps - sph * cps, cph * cth],
        ]
    )


def quat_to_dcm(quat: jnp.ndarray) -> jnp.ndarray:
    """C_nb [3,3] (body -> NED) of a unit quaternion [q0, q1, q2, q3]."""
    q0, q1, q2, q3 = quat[0], quat[1], quat[2], quat[3]
    return jnp.array(
        [
            [1 - 2 * (q2 * q2 + q3 * q3), 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)],
            [2 * (q1 * q2 + q0 * q3), 1 - 2 * (q1 * q1 + q3 * q3), 2 * (q2 * q3 - q0 * q1)],
            [2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), 1 - 2 * (q1 * q1 + q2 * q2)],
        ]
    )


def dcm_to_quat(c_nb: jnp.ndarray) -> jnp.ndarray:
    """Unit quaternion (scalar first, q0 >= 0) of C_nb, branch-free Shepperd's method."""
    tr = c_nb[0, 0] + c_nb[1, 1] + c_nb[2, 2]
    cands = jnp.array(
        [
            [1 + tr, c_nb[2, 1] - c_nb[1, 2], c_nb[0, 2] - c_nb[2, 0], c_nb[1, 0] - c_nb[0, 1]],
            [c_nb[2, 1] - c_nb[1, 2], 1 + 2 * c_nb[0, 0] - tr, c_nb[0, 1] + c_nb[1, 0],
             c_nb[0, 2] + c_nb[2, 0]],
            [c_nb[0, 2] - c_nb[2, 0], c_nb[0, 1] + c_nb[1, 0], 1 + 2 * c_nb[1, 1] - tr,
             c_nb[1, 2] + c_nb[2, 1]],
            [c_nb[1, 0] - c_nb[0, 1], c_nb[0, 2] + c_nb[2, 0], c_nb[1, 2] + c_nb[2, 1],
             1 + 2 * c_nb[2, 2] - tr],
        ]
    )  # fmt: skip
    k = jnp.argmax(jnp.array([tr, c_nb[0, 0], c_nb[1, 1], c_nb[2, 2]]))
    q = cands[k]
    q = q / jnp.linalg.norm(q)
    return q * jnp.where(q[0] < 0, -1.0, 1.0)


def check_shape(x: object, shape: tuple[int, ...], what: str) -> None:
    """Raise ValueError unless ``x`` has the static ``shape`` (checked at trace time, so jit and vmap work:
    under vmap ``x`` is one aircraft's array). ``what`` names the argument and its layout."""
    got = tuple(jnp.shape(x))
    if got != tuple(shape):
        raise ValueError(f"{what} has shape {list(got)}, expected {list(shape)} (vmap for a batch)")


def from_wind(x: jnp.ndarray) -> BodyState:
    """Wind-axis state [10] -> BodyState (x_N = y_E = 0)."""
    check_shape(x, (10,), "wind state x [V, alpha, beta, p, q, r, mu, gamma, chi, h]")
    vt, alpha, beta = x[0], x[1], x[2]
    mu, gamma, chi, h = x[6], x[7], x[8], x[9]
    c_wb = dcm_wind_from_body(alpha, beta)
    c_wn = dcm_321(chi, gamma, mu)
    c_bn = c_wb.T @ c_wn
    uvw = vt * jnp.array([jnp.cos(alpha) * jnp.cos(beta), jnp.sin(beta), jnp.sin(alpha) * jnp.cos(beta)])
    zero = jnp.zeros_like(h)
    return BodyState(
        uvw_fps=uvw,
        pqr_radps=x[3:6],
        quat=dcm_to_quat(c_bn.T),
        pos_ft=jnp.array([zero, zero, h]),
    )


def to_wind(state: BodyState) -> jnp.ndarray:
    """BodyState -> wind-axis state [10] (inertial velocity; see module docstring at gamma=+-90).

    alpha = atan2(w, u), beta = atan2(v, sqrt(u^2 + w^2)) (= asin(v / V)); the direction cosines of alpha
    and beta are ratios of the velocity's components, not sines and cosines of the angles. Its five
    ``arctan2`` are `harv_jax.dynamics.fusion.atan2` (vectorized in float32 on the CPU, where the
    library's ``arctan2`` is a scalar call per element).
    """
    u, v, w = state.uvw_fps[0], state.uvw_fps[1], state.uvw_fps[2]
    uw, vt, ca, sa, cb, sb = airflow_direction(u, v, w)
    alpha, beta = atan2(w, u), atan2(v, uw)
    c_nb = quat_to_dcm(state.quat)
    v_ned = c_nb @ state.uvw_fps
    gamma = atan2(-v_ned[2], jnp.hypot(v_ned[0], v_ned[1]))
    chi = atan2(v_ned[1], v_ned[0])
    # C_wn = C_wb C_bn; mu needs C_wn[1, 2] and C_wn[2, 2]: rows 2 and 3 of C_wb (dcm_wind_from_body) times
    # the third column of C_bn = C_nb^T, the third row of C_nb
    c31, c32, c33 = c_nb[2, 0], c_nb[2, 1], c_nb[2, 2]
    mu = atan2(-ca * sb * c31 + cb * c32 - sa * sb * c33, -sa * c31 + ca * c33)
    return jnp.stack(
        [
            vt,
            alpha,
            beta,
            state.pqr_radps[0],
            state.pqr_radps[1],
            state.pqr_radps[2],
            mu,
            gamma,
            chi,
            state.pos_ft[2],
        ]
    )


def is_finite(state: BodyState) -> jnp.ndarray:
    """True where every component of the state is finite (scalar bool)."""
    leaves = [state.uvw_fps, state.pqr_radps, state.quat, state.pos_ft]
    return jnp.all(jnp.stack([jnp.all(jnp.isfinite(v)) for v in leaves]))
