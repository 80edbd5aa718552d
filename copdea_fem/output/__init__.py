"""Result files: modes.csv / modes.json, ParaView .pvd/.vtu, PNG plots.

Every writer takes a target directory: the staging folder of
:func:`copdea_fem.folders.result_directory`, renamed into place only when
everything is written, so a failed run leaves no half-finished results behind.

The package's parts: :mod:`~copdea_fem.output.tables` (modes.csv/json, the force table),
:mod:`~copdea_fem.output.results` (the result folder of ``solve`` and ``force``) and
:mod:`~copdea_fem.output.plots` (PNG figures).  Below the engines (so that an engine
samples its fields without importing up): :mod:`copdea_fem.paraview.vtu` (the VTU writer,
.pvd collections), :mod:`copdea_fem.paraview.merge` (coincident points merged, quadrants
unfolded), :mod:`copdea_fem.quadrant.fields` (the 3-D engine's fields) and
:mod:`copdea_fem.axisymmetric.fields` (the axisymmetric engine's fields revolved).  Every
name is importable from ``copdea_fem.output`` as before.
"""

from ..paraview.merge import PointMerge, _AirHalves, _jump_vertices, _quadrants, _unfold_cells, \
    _unfold_values
from .plots import _headless_vtk, _read_vtu, plot_force_displacement, plot_modes
from ..quadrant.fields import MembraneSampler, air_meshes, mode_meshes, write_air_vtus, \
    write_mode_vtus
from .results import _sector_summary, prestress_summary, write_force_results, \
    write_paraview, write_results
from ..axisymmetric.fields import RevolvedMembraneSampler, _harmonics, revolution_angles, \
    revolved_air_meshes, revolved_mode_meshes, revolved_sampler, write_revolved_air_vtus, \
    write_revolved_mode_vtus
from .tables import MODE_COLUMNS, _json, frequency_table, mode_rows, write_force_csv, \
    write_json, write_modes
from ..paraview.vtu import VTU_COMPRESSION, CellBlock, VtuMesh, _VTK_CELLS, _VTK_ORDER, \
    _VTK_TYPES, _safe, _write_all, membrane_mesh, write_membrane_vtu, write_pvd, write_vtu

__all__ = ["MODE_COLUMNS", "MembraneSampler", "PointMerge", "RevolvedMembraneSampler",
           "VTU_COMPRESSION", "VtuMesh", "air_meshes", "frequency_table", "membrane_mesh",
           "mode_meshes", "mode_rows", "plot_force_displacement", "plot_modes",
           "prestress_summary", "revolution_angles", "revolved_air_meshes",
           "revolved_mode_meshes", "revolved_sampler", "write_air_vtus", "write_force_csv",
           "write_force_results", "write_json", "write_membrane_vtu", "write_mode_vtus",
           "write_modes", "write_paraview", "write_pvd", "write_results",
           "write_revolved_air_vtus", "write_revolved_mode_vtus", "write_vtu"]
