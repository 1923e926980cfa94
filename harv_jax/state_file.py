"""Initial states from files: the state files ``fly``, ``compare`` and ``optimal`` read, and the limits of a
physically meaningful initial state (``simulate`` checks its ``--state`` against them too)."""

from __future__ import annotations

import json
import math
from pathlib import Path

from harv_jax.errors import UsageError
from harv_jax.task.spec import H0_FT

#: Built-in scenarios of ``fly`` (anything else is a state file).
SCENARIOS = ("spin", "random")
REQUIRED_STATE_NAMES = ("V", "alpha", "beta", "p", "q", "r", "mu", "gamma")
#: Physically meaningful initial states (name -> (low, high, unit)): speeds up to about Mach 2.7, body rates
#: beyond any spin or tumble of this aircraft excluded, altitudes inside the atmosphere model (troposphere
#: and lower stratosphere, 20 km).
STATE_LIMITS = {
    "V": (1.0, 3000.0, "ft/s"),
    "alpha": (-math.pi, math.pi, "rad"),
    "beta": (-1.5707, 1.5707, "rad"),
    "p": (-10.0, 10.0, "rad/s"),
    "q": (-10.0, 10.0, "rad/s"),
    "r": (-10.0, 10.0, "rad/s"),
    "mu": (-2 * math.pi, 2 * math.pi, "rad"),
    "gamma": (-math.pi / 2, math.pi / 2, "rad"),
    "chi": (-2 * math.pi, 2 * math.pi, "rad"),
    "h": (0.0, 65_000.0, "ft"),
}


def validate_state(state: dict[str, float]) -> None:
    """Raise UsageError for a physically meaningless initial state (outside [`STATE_LIMITS`][])."""
    for name, v in state.items():
        if name not in STATE_LIMITS:
            continue
        lo, hi, unit = STATE_LIMITS[name]
        if not (math.isfinite(v) and lo <= v <= hi):
            raise UsageError(f"state {name}={v} {unit} is outside the allowed [{lo:g}, {hi:g}] {unit}")


#: Columns a state file may hold besides the state: those of a ``harv-jax simulate`` trajectory.csv (ignored).
IGNORED_STATE_COLUMNS = ("t", "de", "da", "dr")


def _read_state_raw(path: Path) -> dict:
    name = str(path)
    if path.suffix.lower() not in (".json", ".csv"):
        raise UsageError(f"state file {name!r} must end in .json or .csv")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise UsageError(f"state file {name!r} is not UTF-8 text; expected JSON or CSV") from None
    except OSError as e:
        raise UsageError(f"state file {name!r} cannot be read ({e.strerror or type(e).__name__})") from None
    if not text.strip():
        raise UsageError(f"state file {name!r} is empty; needs {', '.join(REQUIRED_STATE_NAMES)}")
    if path.suffix.lower() == ".json":
        try:
            raw = json.loads(text)
        except json.JSONDecodeError as e:
            raise UsageError(f"state file {name!r} is not valid JSON: {e.msg}") from None
        except RecursionError:
            raise UsageError(f"state file {name!r} is nested too deeply; expected {{name: value}}") from None
        if not isinstance(raw, dict):
            raise UsageError(f"state file {name!r} must hold a JSON object of name: value")
        for k, v in raw.items():
            if isinstance(v, bool) or not isinstance(v, int | float):
                raise UsageError(f"state file {name!r}: {k}={v!r} is not a number")
        return raw
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if len(lines) < 2:
        raise UsageError(f"state file {name!r} needs a header row and a data row")
    names = [s.strip() for s in lines[0].split(",")]
    values = [s.strip() for s in lines[1].split(",")]
    if len(values) != len(names):
        raise UsageError(f"state file {name!r}: {len(names)} header names but {len(values)} values")
    if len(set(names)) != len(names):
        raise UsageError(f"state file {name!r}: a header name appears twice ({', '.join(names)})")
    return dict(zip(names, values, strict=True))


def load_state_file(path: Path) -> dict[str, float]:
    """Initial wind state from a JSON object or a CSV with a header row (first data row is used).

    Required names: V, alpha, beta, p, q, r, mu, gamma (ft/s, rad, rad/s); optional chi (rad, 0) and
    h (ft, 25,000). The columns t, de, da, dr of a ``harv-jax simulate`` trajectory.csv are ignored; any other
    name, a missing one, a value that is not a finite number or a state outside [`STATE_LIMITS`][] is a
    UsageError.
    """
    if not path.is_file():
        raise UsageError(
            f"--scenario {str(path)!r} is neither {' nor '.join(SCENARIOS)} nor an existing file"
        )
    raw = _read_state_raw(path)
    state = {"chi": 0.0, "h": H0_FT}
    known = (*REQUIRED_STATE_NAMES, "chi", "h")
    unknown = [n for n in raw if n not in known and n not in IGNORED_STATE_COLUMNS]
    if unknown:
        raise UsageError(
            f"state file {str(path)!r}: unknown name {unknown[0]!r}; allowed: {', '.join(known)} "
            f"(and {', '.join(IGNORED_STATE_COLUMNS)}, ignored)"
        )
    missing = [n for n in REQUIRED_STATE_NAMES if n not in raw]
    if missing:
        raise UsageError(
            f"state file {str(path)!r} lacks {', '.join(missing)}; needs {', '.join(REQUIRED_STATE_NAMES)}"
        )
    for name in known:
        if name not in raw:
            continue
        try:
            v = float(raw[name])
        except (TypeError, ValueError):
            raise UsageError(f"state file {str(path)!r}: {name}={raw[name]!r} is not a number") from None
        except OverflowError:  # an integer beyond any float
            v = math.inf
        if not math.isfinite(v):
            raise UsageError(f"state file {str(path)!r}: {name}={raw[name]} is not finite")
        state[name] = v
    validate_state(state)
    if state["h"] <= 0:
        raise UsageError(f"state file {str(path)!r}: h={state['h']} ft must be > 0")
    return state
