"""
G1 modes with pyvista (and ParaView)
====================================

The fully-coupled modes of the paper's actuator G1 at z = 16 mm and V_b = 2 kV under the
square frame, on the coarse mesh of ``studies/g1_z16_v2_quick.yaml`` (the 3-D quadrant
engine), through the Python API: the mode table, a mode shape and the air's pressure.
"""

# %%
# Load the study (validated, every value in SI) and solve.  Nothing is written.
import tempfile
from pathlib import Path

import pyvista as pv

import copdea_fem as cf

# the repository root (the tutorials run in docs/tutorials)
ROOT = next(path for path in (Path.cwd(), *Path.cwd().parents) if (path / "studies").is_dir())

study = cf.load_study(ROOT / "studies/g1_z16_v2_quick.yaml",
                      {"eigen.f_max": "560 Hz", "output.plots": False})
print(study.load)                         # z [m], voltage [V]
solution = cf.solve(study)

# %%
# The modes: the columns of ``modes.csv`` as a :class:`pandas.DataFrame`.  Each coupled
# mode carries the dry frequency of the same mode on the same mesh, its added-mass ratio
# ``(f_dry / f)^2 - 1`` and its radiation damping ratio.
solution.modes[["label", "kind", "freq_hz", "dry_freq_hz", "added_mass_ratio",
                "damping_ratio", "symmetry"]]

# %%
# A mode shape: the whole membrane (the quadrant's field unfolded by its parity), warped by
# the real part of the displacement and coloured by the normal displacement.
membrane = solution.membrane("(2,1)a")
print(membrane)
warped = membrane.warp_by_vector("displacement_real", factor=0.004)
plotter = pv.Plotter(window_size=(600, 450))
plotter.add_mesh(warped, scalars="normal_displacement_real", cmap="coolwarm")
plotter.view_isometric()
plotter.show()

# %%
# The air of the (0,1) mode, sliced on the symmetry plane y = 0.  The quadrant copies are
# merged on the mirror planes, so the slice is exact there (its area equals that of a
# slice 0.1 mm beside it).
air = solution.air("(0,1)")
cut = air.slice(normal="y", origin=(0, 0, 0))
print(f"slice on y = 0: {cut.area:.5f} m^2, 0.1 mm beside: "
      f"{air.slice(normal='y', origin=(0, 1e-4, 0)).area:.5f} m^2")
plotter = pv.Plotter(window_size=(600, 450))
plotter.add_mesh(cut, scalars="pressure_real", cmap="RdBu_r")
plotter.view_xz()
plotter.show()

# %%
# For ParaView: ``write`` puts the files of ``copdea-fem solve --out`` in a folder; open
# ``modes.pvd`` and ``air.pvd`` there (ParaView steps through the modes as time steps).
folder = solution.write(Path(tempfile.mkdtemp()) / "g1_quick")
print(sorted(path.name for path in folder.iterdir())[:8], "...")
