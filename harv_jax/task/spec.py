"""The paper's problem as numbers, each defined once and cited.

Sources: the paper's Tables "Observation and Action Space" and "Bounds for random initialization of
state" and Sec. IV-A/VI; docs/model.md ("Envelope and reset bounds", "Reference trim").
Units: ft, ft/s, rad, rad/s, s.
"""

from __future__ import annotations

import math

from harv_jax.units import RAD_PER_DEG

#: Control and integration step, s (paper: 0.01 s, 100 Hz).
DT_S = 0.01
#: Initial (true) altitude, ft. The paper starts its altitude record at 0 ft only to show the loss of
#: altitude; the model needs a true altitude for the air density, and 25,000 ft is the
#: reference trim's altitude (docs/model.md).
H0_FT = 25_000.0
#: Altitude floor, ft: the ground (the paper has none; ``-inf`` disables it).
H_FLOOR_FT = 0.0

#: Envelope (paper observation ranges); leaving it ends an episode or counts as a departure.
V_MIN_FPS = 0.0
V_MAX_FPS = 2000.0
ALPHA_MIN_RAD = -0.244
ALPHA_MAX_RAD = 1.571
RATE_MAX_RADPS = 10.0 * math.pi
GAMMA_MAX_RAD = 1.745

#: Sampled components of the wind state at reset, in ``WIND_STATE_NAMES`` order (chi and h are fixed).
RESET_STATE_NAMES: tuple[str, ...] = ("V", "alpha", "beta", "p", "q", "r", "mu", "gamma")
#: Paper Table reset bounds (ft/s, rad, rad/s), keyed by state name.
RESET_BOUNDS: dict[str, tuple[float, float]] = {
    "V": (100.0, 1500.0),
    "alpha": (-0.175, 1.047),
    "beta": (-0.262, 0.262),
    "p": (-2.094, 2.094),
    "q": (-1.047, 1.047),
    "r": (-0.524, 0.524),
    "mu": (-3.142, 3.142),
    "gamma": (-1.047, 1.047),
}
#: Paper Table bounds of the target angle of attack alpha_d, rad (beta_d = mu_d = 0).
ALPHA_TARGET_BOUNDS_RAD: tuple[float, float] = (-0.085, 0.68)
#: The target of the paper's Monte Carlo and spin studies, rad (20 deg).
ALPHA_TARGET_RAD = 0.349
#: Sideslip and bank targets, rad (paper: 0).
BETA_TARGET_RAD = 0.0
MU_TARGET_RAD = 0.0

#: Recovery criterion (issue's; the Monte Carlo and the reward's ``recovered_tol``): |e_alpha| < 2 deg,
#: |e_beta| < 1 deg, |e_mu| < 2 deg (wrapped), ||omega|| < 0.17 rad/s (the reward's blend threshold,
#: paper Sec. IV-A), held over the last 10 s of a run.
RECOVERY_ALPHA_TOL_RAD = 2.0 * RAD_PER_DEG
RECOVERY_BETA_TOL_RAD = 1.0 * RAD_PER_DEG
RECOVERY_MU_TOL_RAD = 2.0 * RAD_PER_DEG
RECOVERY_OMEGA_TOL_RADPS = 0.17
RECOVERY_HOLD_S = 10.0
