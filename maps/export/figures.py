"""The figures of one plan shared by its outputs (:class:`PlanFigures`), in a module of its own that imports no
matplotlib: the trial cards (:mod:`maps.export.card`) hold one, and a run whose PNGs are all given (a cached plan at
another start time, :func:`cli.drawer.draw_here`) writes its cards without importing pyplot and the Agg backend
(about 0.3 s of CPU). The figures themselves are drawn by :mod:`maps.export.plots`, which the PDF card imports too;
pyplot is imported only when a figure is drawn."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from maps.plan import Plan

STATES_DPI = 110
TRACK_DPI = 130
_DPI = {"states": STATES_DPI, "track": TRACK_DPI}  # each figure's default dpi, saved at its own size (no bbox_inches)


class PlanFigures:
    """The figures of one plan, each drawn once and shared by the HTML trial card's images and
    the PNG exports (the PDF card draws its own map and states page): drawing a figure with its
    layout passes costs as much as saving it. ``close()`` when done (figures hold memory until closed)."""

    def __init__(self, plan: Plan, sea_map: Any = None) -> None:
        self.plan, self.sea_map = plan, sea_map
        self._figs: dict[str, Any] = {}
        self._png: dict[tuple[str, int], bytes] = {}

    def figure(self, name: str) -> Any:
        """'states' (:func:`maps.export.plots.states_figure`) or 'track' (:func:`maps.export.plots.track_figure`),
        built on first use."""
        if name not in self._figs:
            from maps.export.plots import states_figure, track_figure

            self._figs[name] = states_figure(self.plan) if name == "states" else track_figure(self.plan, self.sea_map)
        return self._figs[name]

    def owns(self, fig: Any) -> bool:
        return any(fig is f for f in self._figs.values())

    def png(self, name: str, dpi: int | None = None) -> bytes:
        """The figure as PNG bytes, rendered once per dpi (the map cropped to what is drawn)."""
        key = (name, dpi or _DPI[name])
        if key not in self._png:  # the figure's own size: encoded by figure_png
            from primitives.io import figure_png

            self._png[key] = figure_png(self.figure(name), key[1])
        return self._png[key]

    def adopt_png(self, name: str, data: bytes, dpi: int | None = None) -> None:
        """Use ``data`` as the PNG of figure ``name`` at ``dpi``: the bytes :meth:`png` gave for
        the same plan in another process (``shiptrial plan`` draws its figures in two)."""
        self._png[(name, dpi or _DPI[name])] = data

    def save(self, name: str, path: str | Path, dpi: int | None = None) -> Path:
        """Write the figure to ``path`` (PNG from the shared render, other formats by suffix)."""
        from primitives.io import atomic_savefig, atomic_write_bytes

        if Path(path).suffix.lower() in ("", ".png"):
            return atomic_write_bytes(path, self.png(name, dpi))
        return atomic_savefig(self.figure(name), path, dpi=dpi or _DPI[name], bbox_inches=None)

    def close(self) -> None:
        if self._figs:  # none drawn (every PNG adopted): matplotlib's pyplot is not needed, nor imported
            import matplotlib.pyplot as plt

            for f in self._figs.values():
                plt.close(f)
        self._figs.clear()

    def __enter__(self) -> PlanFigures:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
