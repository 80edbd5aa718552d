"""PNG plots of ``solve`` and ``force``."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

#: matplotlib's "coolwarm" (K. Moreland, "Diverging color maps for scientific
#: visualization", 2009): its 33 control points, RGB in [0, 1], interpolated linearly
COOLWARM = np.array([
    (0.2298057, 0.298717966, 0.753683153), (0.26623388, 0.353094838, 0.801466763),
    (0.30386891, 0.406535296, 0.84495867), (0.342804478, 0.458757618, 0.883725899),
    (0.38301334, 0.50941904, 0.917387822), (0.424369608, 0.558148092, 0.945619588),
    (0.46666708, 0.604562568, 0.968154911), (0.509635204, 0.648280772, 0.98478814),
    (0.552953156, 0.688929332, 0.995375608), (0.596262162, 0.726149107, 0.999836203),
    (0.639176211, 0.759599947, 0.998151185), (0.681291281, 0.788964712, 0.990363227),
    (0.722193294, 0.813952739, 0.976574709), (0.761464949, 0.834302879, 0.956945269),
    (0.798691636, 0.849786142, 0.931688648), (0.833466556, 0.860207984, 0.901068838),
    (0.865395197, 0.86541021, 0.865395561), (0.897787179, 0.848937047, 0.820880546),
    (0.924127593, 0.827384882, 0.774508472), (0.944468518, 0.800927443, 0.726736146),
    (0.958852946, 0.769767752, 0.678007945), (0.96732803, 0.734132809, 0.628751763),
    (0.969954137, 0.694266682, 0.579375448), (0.966811177, 0.650421156, 0.530263762),
    (0.958003065, 0.602842431, 0.481775914), (0.943660866, 0.551750968, 0.434243684),
    (0.923944917, 0.49730856, 0.387970225), (0.89904617, 0.439559467, 0.343229596),
    (0.869186849, 0.378313092, 0.300267182), (0.834620542, 0.312874446, 0.259301199),
    (0.795631745, 0.24128379, 0.220525627), (0.752534934, 0.157246067, 0.184115123),
    (0.705673158, 0.01555616, 0.150232812)])
#: one panel of modes.png [px] and the band above it that holds the title
PANEL_PX, TITLE_PX = 300, 26


def plot_modes(path: Path, vtu_files: list, modes, columns: int = 4) -> None:
    """PNG of the lowest structural modes seen from above, coloured by the normal
    displacement (red up, blue down, each mode on its own symmetric scale).

    ``vtu_files``: the modes' VTU files, or their :class:`~copdea_fem.vtu.VtuMesh`
    objects (as written, not read back).  Nodal diameters and circles show as the pale
    lines.  Drawn with numpy (:class:`Raster`: values interpolated linearly inside each
    triangle, as matplotlib's gouraud ``tripcolor``) and Pillow: matplotlib's import and
    ``savefig`` took ~2 s of the baffled G1 command's ~3 s of result files (issue 25).
    """
    from PIL import Image, ImageDraw, ImageFont

    count = len(vtu_files)
    if count == 0:
        return
    width, rows = min(columns, count), (count + columns - 1) // columns
    picture = np.full((rows * (PANEL_PX + TITLE_PX), width * PANEL_PX, 3), 255, dtype=np.uint8)
    titles, raster = [], None
    for k, (item, mode) in enumerate(zip(vtu_files, modes)):
        mesh = item if hasattr(item, "points") else _read_vtu(item)
        points, triangles = np.asarray(mesh.points)[:, :2], np.asarray(mesh.cells[0].data)
        values = np.asarray(mesh.point_data["normal_displacement_real"], dtype=float)
        limit = float(np.abs(values).max()) or 1.0
        if raster is None or not raster.covers(points, triangles):
            raster = Raster(points, triangles, PANEL_PX - 8)
        row, column = divmod(k, width)
        top, left = row * (PANEL_PX + TITLE_PX) + TITLE_PX + 4, column * PANEL_PX + 4
        picture[top:top + PANEL_PX - 8, left:left + PANEL_PX - 8] = raster.rgb(values / limit)
        titles.append(((column + 0.5) * PANEL_PX, row * (PANEL_PX + TITLE_PX) + TITLE_PX // 2,
                       f"{mode.label}  {mode.freq_hz:.1f} Hz"))
    canvas = Image.fromarray(picture)
    draw = ImageDraw.Draw(canvas)
    font = ImageFont.load_default(size=15)
    for x, y, text in titles:
        draw.text((x, y), text, fill=(0, 0, 0), font=font, anchor="mm")
    write_png(path, np.asarray(canvas))


def write_png(path: Path, rgb: np.ndarray) -> None:
    """An (height, width, 3) array of RGB bytes as a PNG file: 8-bit truecolour, every
    row unfiltered, deflated at zlib's level 1 (PNG specification, ISO/IEC 15948).

    Pillow's encoder (``compress_level=1``) tries its filters on every row: 41 ms for
    modes.png (1200 x 652 px) where this takes 12 ms, for a smaller file of the same
    pixels (378 against 439 kB).
    """
    import struct
    import zlib

    rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
    height, width, _ = rgb.shape
    rows = np.zeros((height, 1 + 3 * width), dtype=np.uint8)    # filter byte 0: none
    rows[:, 1:] = rgb.reshape(height, -1)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data)))

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)   # 8 bits, RGB
    with open(path, "wb") as handle:
        handle.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
                     + chunk(b"IDAT", zlib.compress(rows.tobytes(), 1)) + chunk(b"IEND", b""))


def rasterise(points: np.ndarray, triangles: np.ndarray, values: np.ndarray,
              size: int) -> np.ndarray:
    """A (size, size) image of a field on triangles seen from above (x right, y up), the
    mesh's bounding box fitted with equal scales; ``values`` at the points are interpolated
    linearly inside each triangle (barycentric weights at the pixel centres); NaN outside
    the mesh.  (:class:`Raster` once, then :meth:`Raster.image` per field.)"""
    return Raster(points, triangles, size).image(values)


#: pixel tests per vectorised block of :class:`Raster`
_RASTER_BLOCK = 32768


class Raster:
    """Which triangle covers each pixel centre and its barycentric weights there: the modes
    of one result share their mesh, so modes.png finds them once for all its panels."""

    def __init__(self, points: np.ndarray, triangles: np.ndarray, size: int):
        self.points, self.triangles = np.asarray(points, dtype=float), np.asarray(triangles)
        self.size = size
        points = self.points
        low, high = points.min(axis=0), points.max(axis=0)
        scale = (size - 1) / max(float((high - low).max()), 1e-300)
        centre = 0.5 * (low + high)
        pixel = np.column_stack([(points[:, 0] - centre[0]) * scale + 0.5 * size,
                                 (centre[1] - points[:, 1]) * scale + 0.5 * size])
        corners = pixel[self.triangles]                                   # (t, 3, 2)
        first = np.clip(np.floor(corners.min(axis=1) - 0.5).astype(int), 0, size - 1)
        last = np.clip(np.ceil(corners.max(axis=1) - 0.5).astype(int), 0, size - 1)
        extent = last - first + 1                                         # (t, 2) pixels
        # triangles grouped by their bounding box rounded up to powers of two: one
        # vectorised pass per group over every pixel of the boxes
        bucket = 2 ** np.ceil(np.log2(np.maximum(extent, 1))).astype(int)
        keys = bucket[:, 0] * (4 * size) + bucket[:, 1]
        pixels, owners, weights = [], [], []
        for key in np.unique(keys):
            group = np.flatnonzero(keys == key)
            bx, by = bucket[group[0]]
            ox, oy = np.meshgrid(np.arange(bx), np.arange(by), indexing="ij")
            ox, oy = ox.ravel()[None, :], oy.ravel()[None, :]
            # in blocks of ~32k pixel tests: temporaries that stay in the cache (a fresh
            # process pays a page fault per new page of a large one), the same order
            step = max(1, _RASTER_BLOCK // (bx * by))
            for start in range(0, len(group), step):
                chosen = group[start:start + step]
                px = first[chosen, 0][:, None] + ox                           # (t, bx by)
                py = first[chosen, 1][:, None] + oy
                a, b, c = (corners[chosen, k] for k in range(3))
                denominator = ((b[:, 1] - c[:, 1]) * (a[:, 0] - c[:, 0])
                               + (c[:, 0] - b[:, 0]) * (a[:, 1] - c[:, 1]))
                usable = np.abs(denominator) > 1e-12
                denominator = np.where(usable, denominator, 1.0)[:, None]
                x, y = px + 0.5 - c[:, 0, None], py + 0.5 - c[:, 1, None]
                w0 = ((b[:, 1] - c[:, 1])[:, None] * x
                      + (c[:, 0] - b[:, 0])[:, None] * y) / denominator
                w1 = ((c[:, 1] - a[:, 1])[:, None] * x
                      + (a[:, 0] - c[:, 0])[:, None] * y) / denominator
                w2 = 1.0 - w0 - w1
                inside = ((w0 >= -1e-9) & (w1 >= -1e-9) & (w2 >= -1e-9) & usable[:, None]
                          & (px < size) & (py < size))
                rows, _ = np.nonzero(inside)
                pixels.append((py * size + px)[inside])
                owners.append(chosen[rows])
                weights.append(np.column_stack([w0[inside], w1[inside], w2[inside]]))
        self.pixels = np.concatenate(pixels) if pixels else np.zeros(0, dtype=int)
        self.owners = np.concatenate(owners) if owners else np.zeros(0, dtype=int)
        self.weights = np.concatenate(weights) if weights else np.zeros((0, 3))
        self._corners = None

    def covers(self, points: np.ndarray, triangles: np.ndarray) -> bool:
        """Whether this raster is that of ``points`` (n, 2) and ``triangles``."""
        return (np.shape(points) == self.points.shape and np.shape(triangles)
                == self.triangles.shape and np.array_equal(points, self.points)
                and np.array_equal(triangles, self.triangles))

    def _shade(self, values: np.ndarray) -> np.ndarray:
        """Point ``values`` interpolated at each found pixel (``pixels``, in their order)."""
        if self._corners is None:               # the point of each weight, found once
            self._corners = self.triangles[self.owners]
        return np.sum(self.weights * np.asarray(values, dtype=float)[self._corners], axis=1)

    def image(self, values: np.ndarray) -> np.ndarray:
        """The (size, size) image of point ``values``; NaN off the mesh."""
        image = np.full(self.size * self.size, np.nan)
        image[self.pixels] = self._shade(values)
        return image.reshape(self.size, self.size)

    def rgb(self, values: np.ndarray) -> np.ndarray:
        """The (size, size, 3) RGB bytes of point ``values`` in [-1, 1]: ``colour(image(
        values))``, coloured on the mesh's pixels only (a pixel found twice, on an edge,
        takes its last value in both)."""
        rgb = np.full((self.size * self.size, 3), 255, dtype=np.uint8)
        rgb[self.pixels] = colour(self._shade(values))
        return rgb.reshape(self.size, self.size, 3)


def _lookup_table(count: int = 256) -> np.ndarray:
    """:data:`COOLWARM` sampled at ``count`` evenly spaced values (RGB bytes), as matplotlib
    samples a colormap into its 256-entry table."""
    position = np.linspace(0.0, len(COOLWARM) - 1, count)
    low = np.minimum(position.astype(int), len(COOLWARM) - 2)
    weight = (position - low)[:, None]
    return np.round(255 * ((1 - weight) * COOLWARM[low] + weight * COOLWARM[low + 1])
                    ).astype(np.uint8)


_TABLE = _lookup_table()
_PACKED = _TABLE.view("V3").ravel()         # each colour's 3 bytes as one item


def colour(image: np.ndarray) -> np.ndarray:
    """Values in [-1, 1] -> RGB bytes of :data:`COOLWARM` (its 256-entry table); NaN (outside
    the mesh) white."""
    missing = np.isnan(image)
    position = np.atleast_1d(np.clip(image, -1.0, 1.0))
    position[np.atleast_1d(missing)] = 0.0
    position += 1.0
    position *= 0.5 * (len(_TABLE) - 1)
    index = np.rint(position, out=position).astype(np.intp)
    rgb = _PACKED[index].view(np.uint8).reshape(*np.shape(image), 3)   # one 3-byte read each
    rgb[missing] = 255
    return rgb


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
