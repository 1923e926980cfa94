"""TensorBoard event files of a training run (``tb/`` in the run folder), if tensorboardX is installed."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np


class TensorBoardWriter:
    """Scalars per period to TensorBoard event files (no-op without tensorboardX).

    ``purge_step``: on resume, the env steps to continue from (later events of the old run are dropped).
    """

    def __init__(self, log_dir: Path, purge_step: int | None) -> None:
        try:
            from tensorboardX import SummaryWriter
        except ImportError:
            self.writer = None
            return
        self.writer = SummaryWriter(str(log_dir), purge_step=purge_step)

    def write(self, row: dict[str, Any]) -> None:
        """Mean over seeds of every finite metric of a history row, as ``train/<name>`` at its env steps;
        evaluation entries also per seed (``eval/<name>/seed<i>``) when there are several seeds."""
        if self.writer is None:
            return
        step = int(row["env_steps"])
        for k, v in row.items():
            if k in ("period", "env_steps"):
                continue
            a = np.asarray(v, np.float64).reshape(-1)
            if np.any(np.isfinite(a)):
                self.writer.add_scalar(f"train/{k}", float(np.nanmean(a)), step)
            if k.startswith("eval/") and a.size > 1:
                for i, x in enumerate(a):
                    if np.isfinite(x):
                        self.writer.add_scalar(f"{k}/seed{i}", float(x), step)
        self.writer.flush()

    def close(self) -> None:
        """Close the event file."""
        if self.writer is not None:
            self.writer.close()
