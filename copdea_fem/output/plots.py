"""PNG plots of ``solve`` and ``force``."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np


def plot_modes(path: Path, vtu_files: list, modes, columns: int = 4) -> None:
    """PNG of the lowest structural modes seen from above, coloured by the normal
    displacement (red up, blue down, each mode on its own symmetric scale; matplotlib).

    ``vtu_files``: the modes' VTU files, or their :class:`meshio.Mesh` objects (as written,
    not read back).  Nodal diameters and circles show as the pale lines.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.tri import Triangulation

    count = len(vtu_files)
    if count == 0:
        return
    width, rows = min(columns, count), (count + columns - 1) // columns
    figure = Figure(figsize=(3.0 * width, 3.0 * rows), dpi=100)
    FigureCanvasAgg(figure)
    for k, (item, mode) in enumerate(zip(vtu_files, modes)):
        mesh = item if hasattr(item, "points") else _read_vtu(item)
        points, triangles = np.asarray(mesh.points), np.asarray(mesh.cells[0].data)
        values = np.asarray(mesh.point_data["normal_displacement_real"], dtype=float)
        limit = float(np.abs(values).max()) or 1.0
        axis = figure.add_subplot(rows, width, k + 1)
        axis.tripcolor(Triangulation(points[:, 0], points[:, 1], triangles), values,
                       cmap="coolwarm", vmin=-limit, vmax=limit, shading="gouraud")
        axis.set_aspect("equal")
        axis.set_axis_off()
        axis.set_title(f"{mode.label}  {mode.freq_hz:.1f} Hz", fontsize=10)
    figure.subplots_adjust(left=0.01, right=0.99, bottom=0.01, top=1 - 0.3 / (3.0 * rows),
                           wspace=0.02, hspace=0.12)
    figure.savefig(path)


def _read_vtu(path):
    import meshio
    return meshio.read(path)


def _headless_vtk() -> None:
    """Without a display (Linux, no DISPLAY/WAYLAND_DISPLAY) render through EGL.

    VTK's default X window would first fail with a "bad X server connection"
    warning and then fall back to EGL anyway; asking for EGL directly skips
    the warning.  A VTK_DEFAULT_OPENGL_WINDOW set by the user is kept.
    """
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


def plot_force_displacement(path: Path, z_values, voltages, forces) -> None:
    """PNG of F(z) at each voltage (Fig. 4b style)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(5, 4))
    for voltage, force in zip(voltages, forces):
        axis.plot(np.asarray(z_values) * 1e3, force, marker="o", ms=3,
                  label=f"V = {voltage / 1e3:g} kV")
    axis.set_xlabel("disc displacement z [mm]")
    axis.set_ylabel("axial force F [N]")
    axis.grid(alpha=0.3)
    axis.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)
