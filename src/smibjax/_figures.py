"""Figure helpers without pyplot: a figure and its axes (`subplots`), the formats
matplotlib writes, and an atomic `save_figure` in the format a file name's suffix
names. Used by the command line's plots and the tuner's report; importing it
selects no matplotlib backend."""

from __future__ import annotations

import os

from ._files import atomic_write

__all__ = [
    "subplots",
    "save_figure",
    "plot_formats",
    "check_plot_path",
    "mark_events",
    "clip_to_applied",
]


def plot_formats() -> list[str]:
    """File name suffixes (without the dot) of the formats written here: matplotlib's
    own vector and raster writers (pgf, which needs LaTeX, and the formats that rest
    on optional Pillow plugins are left out)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    own = {"eps", "jpeg", "jpg", "pdf", "png", "ps", "svg", "svgz", "tif", "tiff"}
    return sorted(own & set(FigureCanvasAgg.get_supported_filetypes()))


def check_plot_path(path, option: str = "--plot"):
    """`path` as a Path when its suffix names a format matplotlib writes (.png, .pdf,
    .svg, ...); otherwise a one-line `ParameterError`."""
    from pathlib import Path

    from ._parameters import ParameterError

    p = Path(path)
    fmt = p.suffix[1:].lower()
    formats = plot_formats()
    if fmt not in formats:
        raise ParameterError(
            f"{option} = {str(p)!r} is not allowed: must end in one of "
            f"{', '.join('.' + f for f in formats)}"
        )
    return p


def subplots(nrows: int = 1, ncols: int = 1, **kw):
    """(figure, axes) as `pyplot.subplots` makes them, without pyplot: `figsize`
    goes to the figure, the rest to `Figure.subplots`."""
    from matplotlib.figure import Figure  # (loaded only when a figure is drawn)

    fig = Figure(figsize=kw.pop("figsize", None))
    return fig, fig.subplots(nrows, ncols, **kw)


def save_figure(fig, path, dpi: int = 110) -> None:
    """Atomically write `fig` in the format its file name's suffix asks for (PNG
    without one), at `dpi` dots per inch."""
    fmt = os.path.splitext(str(path))[1][1:].lower() or "png"
    atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format=fmt))


_EVENTS = (("fault", "firebrick"), ("clear", "darkorange"), ("reclose", "seagreen"))


def mark_events(ax, events, legend: bool = False) -> None:
    """Dotted vertical lines at the fault, clearing and reclosing times (s);
    `events` = (t_fault, t_clear, t_reclose), None: none to mark."""
    if events is None:
        return
    for (name, color), t in zip(_EVENTS, events, strict=True):
        ax.axvline(t, color=color, ls=":", lw=1.1, label=name if legend else None)


def clip_to_applied(ax, applied, commanded) -> None:
    """Where the commanded input (before the limits) leaves the applied input's
    range by more than a margin, the y axis spans the applied input (with room)
    and the commanded peak (pu) is stated on the panel. NaN samples are ignored."""
    import numpy as np

    a = np.asarray(applied, dtype=float)
    c = np.asarray(commanded, dtype=float)
    a, c = a[np.isfinite(a)], c[np.isfinite(c)]
    if not (a.size and c.size):
        return
    lo, hi = float(a.min()), float(a.max())
    pad = max(0.15 * (hi - lo), 0.05 * max(abs(lo), abs(hi)), 1e-3)
    if c.min() < lo - pad or c.max() > hi + pad:
        ax.set_ylim(lo - pad, hi + pad)
        peak = float(c[np.argmax(np.abs(c))])
        ax.text(
            0.99,
            0.96,
            f"commanded clipped: peak {peak:.3g} pu",
            transform=ax.transAxes,
            ha="right",
            va="top",
            fontsize=7,
            color="dimgray",
        )
