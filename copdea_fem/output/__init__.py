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

#: where each name of the package lives (imported on first use, PEP 562: a bare solve
#: needs the tables only, not the ParaView writers, the plots or the 3-D engine's fields)
_HOMES = {
    "CellBlock": "..paraview.vtu",
    "MODE_COLUMNS": ".tables",
    "MembraneSampler": "..quadrant.fields",
    "PointMerge": "..paraview.merge",
    "RevolvedMembraneSampler": "..axisymmetric.fields",
    "VTU_COMPRESSION": "..paraview.vtu",
    "VtuMesh": "..paraview.vtu",
    "_AirHalves": "..paraview.merge",
    "_VTK_CELLS": "..paraview.vtu",
    "_VTK_ORDER": "..paraview.vtu",
    "_VTK_TYPES": "..paraview.vtu",
    "_harmonics": "..axisymmetric.fields",
    "_headless_vtk": ".plots",
    "_json": ".tables",
    "_jump_vertices": "..paraview.merge",
    "_quadrants": "..paraview.merge",
    "_read_vtu": ".plots",
    "_safe": "..paraview.vtu",
    "_sector_summary": ".results",
    "_unfold_cells": "..paraview.merge",
    "_unfold_values": "..paraview.merge",
    "_write_all": "..paraview.vtu",
    "air_meshes": "..quadrant.fields",
    "frequency_table": ".tables",
    "membrane_mesh": "..paraview.vtu",
    "mode_meshes": "..quadrant.fields",
    "mode_rows": ".tables",
    "plot_force_displacement": ".plots",
    "plot_modes": ".plots",
    "prestress_summary": ".results",
    "revolution_angles": "..axisymmetric.fields",
    "revolved_air_meshes": "..axisymmetric.fields",
    "revolved_mode_meshes": "..axisymmetric.fields",
    "revolved_sampler": "..axisymmetric.fields",
    "write_air_vtus": "..quadrant.fields",
    "write_force_csv": ".tables",
    "write_force_results": ".results",
    "write_json": ".tables",
    "write_membrane_vtu": "..paraview.vtu",
    "write_mode_vtus": "..quadrant.fields",
    "write_modes": ".tables",
    "write_paraview": ".results",
    "write_pvd": "..paraview.vtu",
    "write_results": ".results",
    "write_revolved_air_vtus": "..axisymmetric.fields",
    "write_revolved_mode_vtus": "..axisymmetric.fields",
    "write_vtu": "..paraview.vtu",
}

__all__ = ["MODE_COLUMNS", "MembraneSampler", "PointMerge", "RevolvedMembraneSampler",
           "VTU_COMPRESSION", "VtuMesh", "air_meshes", "frequency_table", "membrane_mesh",
           "mode_meshes", "mode_rows", "plot_force_displacement", "plot_modes",
           "prestress_summary", "revolution_angles", "revolved_air_meshes",
           "revolved_mode_meshes", "revolved_sampler", "write_air_vtus", "write_force_csv",
           "write_force_results", "write_json", "write_membrane_vtu", "write_mode_vtus",
           "write_modes", "write_paraview", "write_pvd", "write_results",
           "write_revolved_air_vtus", "write_revolved_mode_vtus", "write_vtu"]


def __getattr__(name: str):
    """A name of :data:`_HOMES` from its module, imported on first use."""
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib
    value = getattr(importlib.import_module(_HOMES[name], __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_HOMES))
