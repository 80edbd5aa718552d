"""PNG plots of ``solve`` (``modes.png``) and ``force`` (``force_displacement.png``).

Drawn on matplotlib's Agg canvas (:class:`~matplotlib.figure.Figure` with
:class:`~matplotlib.backends.backend_agg.FigureCanvasAgg`), not through pyplot: no global
figure registry to clean up and no GUI backend chosen behind the caller's back.  The module
is imported only when ``output.plots`` is on (:mod:`copdea_fem.output.results`), so a solve
without plots does not import matplotlib.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: one panel of modes.png [px] (the mesh fitted 4 px inside it) and the title band above it
PANEL_PX, TITLE_PX = 300, 26
#: modes.png's resolution: one point of the figure per pixel
MODES_DPI = 100


def plot_modes(path: Path, shapes: list, modes, columns: int = 4) -> None:
    """PNG of the plotted modes seen from above (x right, y up), coloured by the normal
    displacement with matplotlib's ``coolwarm`` (red up, blue down, each mode on its own
    symmetric scale, so nodal diameters and circles show as the pale lines), ``columns``
    panels a row, each titled with the mode's label and frequency.

    ``shapes``: the modes' :class:`~copdea_fem.vtu.VtuMesh` (points (n, 3), triangles in
    ``cells[0].data``, ``point_data["normal_displacement_real"]``); ``modes``: objects with
    ``label`` and ``freq_hz``.  Values are interpolated linearly inside each triangle
    (gouraud ``tripcolor``).  All panels share one Axes whose data coordinates are the
    picture's pixels: an Axes per panel would lay out ticks and titles that are not shown.
    Nothing is written when there is no mode to plot.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.tri import Triangulation

    count = len(shapes)
    if count == 0:
        return
    width, rows = min(columns, count), (count + columns - 1) // columns
    size_px = (width * PANEL_PX, rows * (PANEL_PX + TITLE_PX))
    figure = Figure(figsize=(size_px[0] / MODES_DPI, size_px[1] / MODES_DPI), dpi=MODES_DPI)
    FigureCanvasAgg(figure)
    axis = figure.add_axes((0.0, 0.0, 1.0, 1.0))
    axis.set_axis_off()
    axis.set_xlim(0, size_px[0])
    axis.set_ylim(size_px[1], 0)                 # row 0 of the picture at the top
    fitted = PANEL_PX - 8
    for k, (mesh, mode) in enumerate(zip(shapes, modes)):
        points = np.asarray(mesh.points, dtype=float)[:, :2]
        values = np.asarray(mesh.point_data["normal_displacement_real"], dtype=float)
        limit = float(np.abs(values).max()) or 1.0
        low, high = points.min(axis=0), points.max(axis=0)
        scale = fitted / max(float((high - low).max()), 1e-300)
        row, column = divmod(k, width)
        centre_x = (column + 0.5) * PANEL_PX
        centre_y = row * (PANEL_PX + TITLE_PX) + TITLE_PX + 0.5 * PANEL_PX
        x = centre_x + scale * (points[:, 0] - 0.5 * (low[0] + high[0]))
        y = centre_y - scale * (points[:, 1] - 0.5 * (low[1] + high[1]))     # y up
        axis.tripcolor(Triangulation(x, y, np.asarray(mesh.cells[0].data)), values / limit,
                       cmap="coolwarm", vmin=-1.0, vmax=1.0, shading="gouraud")
        axis.text(centre_x, centre_y - 0.5 * PANEL_PX - 0.5 * TITLE_PX,
                  f"{mode.label}  {mode.freq_hz:.1f} Hz", ha="center", va="center",
                  fontsize=11)
    # zlib level 1: Pillow's default (6) takes several times longer for this picture
    figure.savefig(path, pil_kwargs={"compress_level": 1})


def plot_force_displacement(path: Path, z_values, voltages, forces) -> None:
    """PNG of the disc force F against its displacement z, one line per voltage
    (Fig. 4b style); ``forces[i]`` holds F at ``z_values`` for ``voltages[i]`` [V]."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(5, 4), dpi=120)
    FigureCanvasAgg(figure)
    axis = figure.add_subplot()
    for voltage, force in zip(voltages, forces):
        axis.plot(np.asarray(z_values) * 1e3, force, marker="o", ms=3,
                  label=f"V = {voltage / 1e3:g} kV")
    axis.set_xlabel("disc displacement z [mm]")
    axis.set_ylabel("axial force F [N]")
    axis.grid(alpha=0.3)
    axis.legend()
    figure.tight_layout()
    figure.savefig(path)
