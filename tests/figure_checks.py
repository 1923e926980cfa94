"""Checks of a matplotlib figure as a reader sees it, without a browser: all it draws inside the figure."""

from __future__ import annotations

import matplotlib.figure


def texts_outside(fig: matplotlib.figure.Figure, tolerance_px: float = 1.0) -> list[str]:
    """What of ``fig`` is drawn beyond its edges: each axes with everything it draws (tick labels, axis
    labels, title, legend), each figure legend and the figure's own texts (the suptitle among them), as
    ``'name' (x0, y0, x1, y1 of width x height px)``."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    w, h = fig.bbox.width, fig.bbox.height
    parts = [(f"axes {ax.get_title() or ax.get_ylabel() or i}", ax) for i, ax in enumerate(fig.axes)]
    parts += [(f"figure legend {i}", leg) for i, leg in enumerate(fig.legends)]
    parts += [(f"text {t.get_text()[:50]!r}", t) for t in fig.texts if t.get_text().strip()]
    bad = []
    for name, artist in parts:
        if not artist.get_visible():
            continue
        b = artist.get_tightbbox(renderer) if hasattr(artist, "get_tightbbox") else None
        b = b if b is not None else artist.get_window_extent(renderer)
        tol = tolerance_px
        if b.x0 < -tol or b.y0 < -tol or b.x1 > w + tol or b.y1 > h + tol:
            bad.append(f"{name} ({b.x0:.0f}, {b.y0:.0f}, {b.x1:.0f}, {b.y1:.0f} of {w:.0f}x{h:.0f})")
    return bad
