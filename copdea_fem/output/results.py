"""The files of ``solve`` and ``force``, written into a staging folder.

The caller (:meth:`copdea_fem.api.Solution.write`, :meth:`copdea_fem.api.ForceCurve.write`)
claims the result folder and stages it (:mod:`copdea_fem.folders`); these functions only
fill the staging folder."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from copdea_fem.output.tables import write_force_csv, write_modes
from copdea_fem.study import Study, dump_resolved
from copdea_fem.vtu import split_cells, write_all, write_pvd, write_vtu

if TYPE_CHECKING:
    from copdea_fem.fe import Mode, PrestressedState, SolveResult


def prestress_summary(state) -> dict:
    """The prestress block of modes.json (SI)."""
    return {"z_m": state.z, "voltage_v": state.voltage, "disc_force_n": state.disc_force,
            "newton_iterations": state.newton_iterations,
            "load_steps": [{"z_m": z, "voltage_v": v, "newton_iterations": it}
                           for z, v, it in state.load_steps]}


def write_solve_files(staging: Path, result: SolveResult, rows: list[dict]) -> None:
    """Every file of ``solve`` for a :class:`copdea_fem.fe.pipeline.SolveResult` (either
    engine) into ``staging``: modes.csv/json with ``rows``
    (:func:`copdea_fem.output.tables.mode_rows`), the resolved study, ParaView files and plots
    as ``output.*`` asks."""
    from copdea_fem.fe import IN_PLANE, OUT_OF_PLANE, PUMPING

    study = result.study
    structural = [mode for mode in result.modes if mode.kind in (OUT_OF_PLANE, PUMPING, IN_PLANE)]
    fields = result.engine.output(result.state, structural)
    extra = {"prestress": prestress_summary(result.state),
             "eigen": {"engine": result.engine.name,
                       "shifts_hz": [float(f) for f in result.eigen.shift_freq_hz],
                       "unknowns": int(result.eigen.unknowns),
                       "factorisations": int(result.eigen.n_factorisations),
                       "symmetry": fields.symmetry,
                       **_sector_summary(result.eigen)},
             "timings_s": result.timings.seconds}
    write_modes(staging, rows, study, extra)
    plotted = [k for k, mode in enumerate(structural) if mode.kind in (OUT_OF_PLANE, PUMPING)][:8]
    if study.output.paraview:
        kept = {k: None for k in plotted}     # the plotted meshes, not read back
        write_paraview(staging, result.state, structural, fields, kept=kept)
        shapes = [kept[k] for k in plotted]
        if result.coupled is not None:
            # structural modes and an enclosure's cavity modes
            indices = [k for k, mode in enumerate(result.modes)
                       if mode.kind != "air" or mode.cavity_orders]
            air_files, times, parts = _air_blocks(staging, fields.air_meshes(
                result.coupled.operators, [result.modes[k] for k in indices],
                [result.coupled.pressures[k] for k in indices]))
            write_pvd(staging / "air.pvd", air_files, times, parts)
    elif study.output.plots:                # only the plotted modes, no file
        shapes = [mesh for _, mesh in fields.mode_meshes([structural[k] for k in plotted])]
    if study.output.plots:
        from copdea_fem.output.plots import plot_modes  # a bare solve does without the plots
        plot_modes(staging / "modes.png", shapes, [structural[k] for k in plotted])


def _air_blocks(staging: Path, meshes) -> tuple[list[Path], list[int], list[int]]:
    """Write each mode's air (``(stem, VtuMesh)`` pairs); an enclosure's air (cell data
    ``cavity``) as its own file ``<stem>_cavity.vtu`` and ParaView block (part 1).
    Returns the files, their time (the mode's number) and part."""
    times, parts = [], []

    def pieces():                      # lazily, as write_all takes them
        for number, (stem, mesh) in enumerate(meshes):
            split = split_cells(mesh, "cavity") if "cavity" in mesh.cell_data else (mesh,)
            names = (stem, f"{stem}_cavity")
            for part, piece in enumerate(split):
                if len(piece.cells[0].data):
                    times.append(number)
                    parts.append(part)
                    yield names[part], piece

    return write_all(staging, pieces()), times, parts


def _sector_summary(eigen_result) -> dict:
    """Per-sector unknowns, shifts and eigenpair counts of a coupled solve (modes.json)."""
    if not hasattr(eigen_result, "by_sector"):
        return {}
    return {"sectors": {name: {"unknowns": part.unknowns, "eigenpairs": len(part),
                               "shifts_hz": [float(f) for f in part.shift_freq_hz]}
                        for name, part in eigen_result.by_sector.items()}}


def write_paraview(directory: Path, state: PrestressedState, modes: list[Mode], fields,
                   kept: dict | None = None) -> list[Path]:
    """prestress.vtu + modes.pvd with one .vtu per mode (revolved to 3-D when axisymmetric).

    ``fields``: the engine's result fields (:meth:`copdea_fem.fe.engines.Engine.output`).
    ``kept``: ``{position in modes: None}``; receives the
    :class:`~copdea_fem.vtu.VtuMesh` of those modes' files (for the plot, without
    reading them back).
    """
    write_vtu(directory / "prestress.vtu", fields.prestress_mesh())
    files = write_all(directory, fields.mode_meshes(modes), kept)
    write_pvd(directory / "modes.pvd", files, list(range(len(files))))
    return files


def write_force_files(staging: Path, study: Study, z_values, voltages, forces) -> None:
    """force_displacement.csv (+ PNG) and study.resolved.yaml of ``force`` into ``staging``."""
    write_force_csv(staging / "force_displacement.csv", z_values, voltages, forces)
    if study.output.plots:
        from copdea_fem.output.plots import plot_force_displacement
        plot_force_displacement(staging / "force_displacement.png", z_values, voltages, forces)
    dump_resolved(study, staging / "study.resolved.yaml")
