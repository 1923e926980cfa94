"""Named unit conversion constants. All code converts through these; no bare 57.29578."""

import math

RAD_PER_DEG = math.pi / 180.0
DEG_PER_RAD = 180.0 / math.pi
M_PER_FT = 0.3048
FT_PER_M = 1.0 / M_PER_FT
G_FPS2 = 32.174  # standard gravity used by the model, ft/s^2 (docs/model.md)
