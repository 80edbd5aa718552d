"""modes.png drawn with numpy and Pillow (copdea_fem/output/plots.py, issue 25)."""

import subprocess
import sys
from pathlib import Path

import numpy as np

from copdea_fem.output.plots import COOLWARM, PANEL_PX, TITLE_PX, colour, rasterise

ROOT = Path(__file__).resolve().parent.parent


def disc(n_r=12, n_t=48, inner=0.3):
    """An annulus of radius 1 triangulated ring by ring: points (n, 2), triangles."""
    r = np.linspace(inner, 1.0, n_r)
    t = 2 * np.pi * np.arange(n_t) / n_t
    points = np.column_stack([(r[:, None] * np.cos(t)).ravel(), (r[:, None] * np.sin(t)).ravel()])
    index = np.arange(n_r * n_t).reshape(n_r, n_t)
    nxt = np.roll(index, -1, axis=1)
    cells = np.concatenate([np.stack([index[:-1], index[1:], nxt[1:]], -1).reshape(-1, 3),
                            np.stack([index[:-1], nxt[1:], nxt[:-1]], -1).reshape(-1, 3)])
    return points, cells


def test_a_linear_field_is_drawn_exactly_where_the_mesh_is():
    """Linear interpolation reproduces a linear field at every pixel centre; pixels off the
    mesh (the hole, the corners) are NaN."""
    points, cells = disc()
    size = 64
    image = rasterise(points, cells, 0.5 * points[:, 0] - 0.25 * points[:, 1], size)
    scale = (size - 1) / 2.0
    centres = (np.arange(size) + 0.5 - 0.5 * size) / scale
    x, y = np.meshgrid(centres, -centres)          # row 0 at the top: y up
    drawn = ~np.isnan(image)
    np.testing.assert_allclose(image[drawn], (0.5 * x - 0.25 * y)[drawn], atol=1e-12)
    radius = np.hypot(x, y)
    # inside the polygon of the outer ring and outside the inner one: drawn
    assert drawn[(radius < 0.95) & (radius > 0.35)].all()
    assert not drawn[(radius > 1.0 + 1e-9) | (radius < 0.3 * np.cos(np.pi / 48) - 1e-9)].any()


def test_colours_are_coolwarm_and_white_off_the_mesh():
    rgb = colour(np.array([[-1.0, 0.0, 1.0, np.nan, -5.0]])).astype(int)
    np.testing.assert_array_equal(rgb[0, 0], np.round(255 * COOLWARM[0]))
    np.testing.assert_allclose(rgb[0, 1], 255 * COOLWARM[16], atol=2)   # the 256-entry table
    np.testing.assert_array_equal(rgb[0, 2], np.round(255 * COOLWARM[-1]))
    np.testing.assert_array_equal(rgb[0, 3], [255, 255, 255])
    np.testing.assert_array_equal(rgb[0, 4], rgb[0, 0])                  # clipped


def test_plot_modes_writes_the_panels_without_matplotlib(tmp_path):
    code = f"""
import sys, types
import numpy as np
sys.path.insert(0, {str(ROOT / "tests")!r})
from test_output_plots import disc
from copdea_fem.output import plot_modes
points, cells = disc()
meshes, modes = [], []
for m in range(5):
    angle = np.arctan2(points[:, 1], points[:, 0])
    mesh = types.SimpleNamespace(points=np.column_stack([points, 0 * points[:, 0]]),
                                 cells=[types.SimpleNamespace(data=cells)],
                                 point_data={{"normal_displacement_real": np.cos(m * angle)}})
    meshes.append(mesh)
    modes.append(types.SimpleNamespace(label=f"({{m}},1)", freq_hz=100.0 * (m + 1)))
plot_modes({str(tmp_path / 'modes.png')!r}, meshes, modes)
print("matplotlib" in sys.modules)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout.split()
    assert out == ["False"]
    from PIL import Image
    picture = np.asarray(Image.open(tmp_path / "modes.png").convert("RGB"))
    assert picture.shape == (2 * (PANEL_PX + TITLE_PX), 4 * PANEL_PX, 3)
    # panel of (1,1): red on the right (+x), blue on the left; the last row's 2nd..4th empty
    top = TITLE_PX + 4
    middle = top + (PANEL_PX - 8) // 2
    right, left = picture[middle, PANEL_PX + PANEL_PX - 20], picture[middle, PANEL_PX + 20]
    assert right[0] > 150 > right[2] and left[2] > 150 > left[0]
    assert (picture[PANEL_PX + TITLE_PX + 40:, PANEL_PX + 10:] == 255).all()
