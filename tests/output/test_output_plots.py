"""modes.png and force_displacement.png (copdea_fem/output/plots.py), read back with Pillow."""

import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from copdea_fem.output.plots import PANEL_PX, TITLE_PX, plot_force_displacement, plot_modes
from copdea_fem.vtu import VtuMesh

ROOT = Path(__file__).resolve().parents[2]


def annulus(n_r=12, n_t=48, inner=0.3):
    """An annulus of radius 1 triangulated ring by ring: points (n, 2), triangles."""
    r = np.linspace(inner, 1.0, n_r)
    t = 2 * np.pi * np.arange(n_t) / n_t
    points = np.column_stack([(r[:, None] * np.cos(t)).ravel(), (r[:, None] * np.sin(t)).ravel()])
    index = np.arange(n_r * n_t).reshape(n_r, n_t)
    nxt = np.roll(index, -1, axis=1)
    cells = np.concatenate([np.stack([index[:-1], index[1:], nxt[1:]], -1).reshape(-1, 3),
                            np.stack([index[:-1], nxt[1:], nxt[:-1]], -1).reshape(-1, 3)])
    return points, cells


def mode_shapes(scale=1.0):
    """Five modes on the annulus: uniform, cos, sin, cos 2, cos 3 of the angle."""
    points, cells = annulus()
    angle = np.arctan2(points[:, 1], points[:, 0])
    fields = [np.ones_like(angle), np.cos(angle), np.sin(angle), np.cos(2 * angle),
              np.cos(3 * angle)]
    shapes = [VtuMesh(np.column_stack([points, np.zeros(len(points))]), [("triangle", cells)],
                      {"normal_displacement_real": scale * field}) for field in fields]
    modes = [types.SimpleNamespace(label=f"mode {k}", freq_hz=100.0 * (k + 1))
             for k in range(len(fields))]
    return shapes, modes


def read_rgb(path):
    with Image.open(path) as image:
        return np.asarray(image.convert("RGB")).astype(int)


def panel(picture, k, columns=4):
    """The mesh area of panel ``k`` and the title band above it."""
    row, column = divmod(k, columns)
    top, left = row * (PANEL_PX + TITLE_PX), column * PANEL_PX
    return (picture[top + TITLE_PX:top + TITLE_PX + PANEL_PX, left:left + PANEL_PX],
            picture[top:top + TITLE_PX, left:left + PANEL_PX])


def red(pixel):
    return pixel[0] > 150 > pixel[2]


def blue(pixel):
    return pixel[2] > 150 > pixel[0]


def test_modes_png_has_a_titled_coloured_panel_per_mode(tmp_path):
    shapes, modes = mode_shapes()
    plot_modes(tmp_path / "modes.png", shapes, modes)
    picture = read_rgb(tmp_path / "modes.png")
    assert picture.shape == (2 * (PANEL_PX + TITLE_PX), 4 * PANEL_PX, 3)
    areas, titles = zip(*(panel(picture, k) for k in range(8)))
    for k in range(5):
        saturation = areas[k].max(axis=2) - areas[k].min(axis=2)
        assert (saturation > 60).mean() > 0.3, k            # coloured, not blank or grey
        assert (titles[k] < 100).all(axis=2).sum() > 30, k  # dark text in the title band
    for k in range(5, 8):                                   # no mode: white
        assert (areas[k] == 255).all() and (titles[k] == 255).all()
    for j in range(5):
        for k in range(j):
            assert np.abs(areas[j] - areas[k]).mean() > 5, (j, k)
    middle, near, far = PANEL_PX // 2, 20, PANEL_PX - 20
    assert red(areas[0][middle, near]) and red(areas[0][near, middle])     # uniform: all red
    assert not red(areas[0][middle, middle])                                 # the hole
    assert red(areas[1][middle, far]) and blue(areas[1][middle, near])      # +x to the right
    assert red(areas[2][near, middle]) and blue(areas[2][far, middle])      # +y up


def test_each_mode_is_drawn_on_its_own_symmetric_scale(tmp_path):
    """The colours follow the shape, not its amplitude."""
    plot_modes(tmp_path / "unit.png", *mode_shapes())
    plot_modes(tmp_path / "tiny.png", *mode_shapes(scale=1e-9))
    unit, tiny = read_rgb(tmp_path / "unit.png"), read_rgb(tmp_path / "tiny.png")
    assert np.abs(unit - tiny).mean() < 0.1


def test_no_mode_writes_no_picture(tmp_path):
    plot_modes(tmp_path / "modes.png", [], [])
    assert not (tmp_path / "modes.png").exists()


def test_force_plot_has_a_line_per_voltage(tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    drawn = []
    savefig = Figure.savefig
    monkeypatch.setattr(Figure, "savefig",
                        lambda self, *args, **kwargs: drawn.append(self)
                        or savefig(self, *args, **kwargs))
    z = np.linspace(0.0, 0.016, 9)
    forces = [0.2 * z * 1e3, 0.3 * z * 1e3 - 0.5, 0.4 * z * 1e3 - 1.0]
    plot_force_displacement(tmp_path / "force.png", z, [0.0, 2000.0, 4000.0], forces)
    (axis,) = drawn[0].axes
    assert [line.get_label() for line in axis.lines] == ["V = 0 kV", "V = 2 kV", "V = 4 kV"]
    for line, force in zip(axis.lines, forces):
        np.testing.assert_allclose(line.get_xdata(), z * 1e3)
        np.testing.assert_allclose(line.get_ydata(), force)
    picture = read_rgb(tmp_path / "force.png")
    assert picture.shape == (480, 600, 3)
    # the lines in the file: matplotlib's first three cycle colours, not the fourth
    colours = [(0x1F, 0x77, 0xB4), (0xFF, 0x7F, 0x0E), (0x2C, 0xA0, 0x2C), (0xD6, 0x27, 0x28)]
    counts = [int((picture == colour).all(axis=2).sum()) for colour in colours]
    assert min(counts[:3]) > 100 and counts[3] == 0


@pytest.mark.parametrize("plot", ["modes", "force"])
def test_plots_do_not_go_through_pyplot(tmp_path, plot):
    """The figures are drawn on an Agg canvas of their own: pyplot (its global figures and
    GUI backend) is never imported."""
    call = {"modes": "plot_modes(out / 'modes.png', [VtuMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "
                     "[('triangle', [[0, 1, 2]])], {'normal_displacement_real': [0, 1, -1]})], "
                     "[SimpleNamespace(label='(0,1)', freq_hz=1.0)])",
            "force": "plot_force_displacement(out / 'f.png', [0, 1e-3], [0.0], [[0, 1]])"}
    code = ("import sys\nfrom pathlib import Path\nfrom types import SimpleNamespace\n"
            "from copdea_fem.output.plots import plot_force_displacement, plot_modes\n"
            "from copdea_fem.vtu import VtuMesh\n"
            f"out = Path({str(tmp_path)!r})\n{call[plot]}\n"
            "print(sorted(m for m in ('matplotlib.figure', 'matplotlib.pyplot') "
            "if m in sys.modules))\n")
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                               cwd=ROOT, check=False)
    assert completed.returncode == 0, completed.stderr[-2000:]
    assert completed.stdout.split("\n")[-2] == "['matplotlib.figure']"
    assert len(list(tmp_path.glob("*.png"))) == 1
