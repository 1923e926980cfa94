"""Command-line options shared by several commands (one definition, one help text)."""

from __future__ import annotations

import typer

POLICY_HELP = (
    "rl/hybrid policy: run folder, .npz, checkpoint\\[@seed], shipped:recovery (default), "
    "shipped:paper-full, shipped:paper-partial."
)
ZETA_HELP = (
    "Hybrid zeta schedule: continuous, hysteresis (the paper's), gated (per channel, from the reaching "
    "condition), always, never."
)


def policy_option():
    """``--policy`` (default None = the default shipped policy, ``shipped:recovery``)."""
    return typer.Option(None, help=POLICY_HELP)


def zeta_option():
    """``--zeta`` (default continuous)."""
    return typer.Option("continuous", help=ZETA_HELP)
