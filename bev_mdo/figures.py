"""Figures drawn without touching the caller's matplotlib: no backend chosen, no rcParams left changed,
no figure left open in pyplot. The plots of the API, of `report` and of the CLI's ``--png`` are
`matplotlib.figure.Figure`s of their own on Agg canvases (saved with ``fig.savefig``; nothing to close),
drawn by functions decorated with `styled`: bev_mdo's style holds inside them, the caller's after."""
from __future__ import annotations

import functools

STYLE = {"axes.formatter.useoffset": False}  # values on the axis, not "0.1 .. 0.5 +3.209e2"


def styled(draw):
    """``draw`` runs with bev_mdo's STYLE over the caller's rcParams, which are back when it returns."""
    @functools.wraps(draw)
    def in_style(*args, **kwargs):
        import matplotlib

        with matplotlib.rc_context(STYLE):
            return draw(*args, **kwargs)
    return in_style


def figure(**kwargs):
    """A figure of its own, as ``pyplot.figure(**kwargs)`` makes one, not registered with pyplot, on an Agg
    canvas (``fig.canvas.get_renderer()`` measures what is drawn)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig


def subplots(*args, figsize=None, layout=None, **kwargs):
    """(figure, axes) as ``pyplot.subplots`` makes them, on a figure of its own."""
    fig = figure(figsize=figsize, layout=layout)
    return fig, fig.subplots(*args, **kwargs)


def colormap(name: str):
    """The colormap ``name`` (``pyplot.get_cmap``)."""
    import matplotlib

    return matplotlib.colormaps[name]
