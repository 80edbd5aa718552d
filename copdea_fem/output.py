"""Result files: modes.csv / modes.json, ParaView .pvd/.vtu, PNG plots.

Every writer takes a target directory; :func:`result_directory` hands out a
temporary sibling that is renamed into place only when everything is written,
so a failed run leaves no half-finished results behind.
"""

from __future__ import annotations

import contextlib
import csv
import json
import shutil
import tempfile
from pathlib import Path

import numpy as np

from .study import Study, dump_resolved, package_versions

MODE_COLUMNS = ("label", "m", "n", "kind", "freq_hz", "freq_im_hz", "damping_ratio",
                "membrane_energy_fraction", "modal_mass", "dry_freq_hz", "added_mass_ratio",
                "normal_fraction", "disc_fraction", "residual")


@contextlib.contextmanager
def result_directory(target: str | Path):
    """Yield a fresh temporary directory; on success it replaces ``target``."""
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    try:
        yield staging
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    if target.exists():
        shutil.rmtree(target)
    staging.rename(target)


def mode_rows(modes, dry_frequencies: dict | None = None) -> list[dict]:
    """One row per mode with :data:`MODE_COLUMNS` (SI: Hz, kg)."""
    rows = []
    for mode in modes:
        dry = (dry_frequencies or {}).get(mode.label, mode.freq_hz)
        rows.append({
            "label": mode.label, "m": mode.m, "n": mode.n, "kind": mode.kind,
            "freq_hz": mode.freq_hz, "freq_im_hz": mode.freq_im_hz,
            "damping_ratio": mode.damping_ratio,
            "membrane_energy_fraction": getattr(mode, "membrane_energy_fraction", 1.0),
            "modal_mass": mode.modal_mass, "dry_freq_hz": dry,
            "added_mass_ratio": (dry / mode.freq_hz) ** 2 - 1 if mode.freq_hz > 0 else 0.0,
            "normal_fraction": mode.normal_fraction, "disc_fraction": mode.disc_fraction,
            "residual": mode.residual})
    return rows


def write_modes(directory: Path, rows: list[dict], study: Study, extra: dict) -> None:
    """modes.csv, modes.json and study.resolved.yaml."""
    with open(directory / "modes.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=MODE_COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({key: (f"{value:.10g}" if isinstance(value, float) else value)
                             for key, value in row.items()})
    document = {"study": study.as_dict(), "provenance": package_versions(), **extra,
                "modes": rows}
    (directory / "modes.json").write_text(json.dumps(document, indent=1, default=_json))
    dump_resolved(study, directory / "study.resolved.yaml")


def _json(value):
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    raise TypeError(f"cannot serialise {type(value).__name__}")


def frequency_table(rows: list[dict], kinds=("pumping", "out-of-plane", "in-plane")) -> str:
    """Plain-text table of the modes for the terminal."""
    lines = [f"{'label':>10} {'kind':>13} {'f [Hz]':>10} {'Im f [Hz]':>10} {'residual':>9}"]
    for row in rows:
        if row["kind"] in kinds:
            lines.append(f"{row['label']:>10} {row['kind']:>13} {row['freq_hz']:10.2f} "
                         f"{row['freq_im_hz']:10.3f} {row['residual']:9.1e}")
    return "\n".join(lines)


# -- ParaView -------------------------------------------------------------------------
def write_membrane_vtu(path: Path, mesh, fields: dict, deformation=None, subdivision: int = 1
                       ) -> Path:
    """VTU of the membrane faces with the given CoefficientFunctions (NGSolve VTKOutput).

    ``deformation`` (a displacement GridFunction) draws the prestressed shape.
    Returns the written file's path.
    """
    import ngsolve as ngs

    names = list(fields)
    if deformation is not None:
        mesh.SetDeformation(deformation)
    try:
        vtk = ngs.VTKOutput(mesh, coefs=[fields[name] for name in names], names=names,
                            filename=str(path.with_suffix("")), subdivision=subdivision)
        vtk.Do(vb=ngs.BND, drawelems=mesh.Boundaries("membrane").Mask())
    finally:
        if deformation is not None:
            mesh.UnsetDeformation()
    return path.with_suffix(".vtu")


def write_pvd(path: Path, files: list[Path], times: list[float]) -> None:
    """A ParaView collection; 'time' is the mode index so ParaView steps through modes."""
    entries = "\n".join(f'    <DataSet timestep="{t:g}" group="" part="0" file="{f.name}"/>'
                        for f, t in zip(files, times))
    path.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
                    f"  <Collection>\n{entries}\n  </Collection>\n</VTKFile>\n")


def write_mode_vtus(directory: Path, state, modes) -> list[Path]:
    """One .vtu per mode on the prestressed shape: displacement re/im/abs, normal velocity."""
    import ngsolve as ngs

    from .membrane import deformed_normal

    complex_modes = any(np.iscomplexobj(mode.vector) for mode in modes)
    real_part, imag_part = ngs.GridFunction(state.space), ngs.GridFunction(state.space)
    normal = deformed_normal(state.displacement)
    files = []
    for number, mode in enumerate(modes):
        real_part.vec.FV().NumPy()[:] = np.real(mode.vector)
        imag_part.vec.FV().NumPy()[:] = np.imag(mode.vector) if complex_modes else 0.0
        omega = 2 * np.pi * abs(complex(mode.freq_hz, mode.freq_im_hz))
        magnitude = ngs.sqrt(real_part * real_part + imag_part * imag_part)
        fields = {"displacement_real": real_part, "displacement_imag": imag_part,
                  "displacement_abs": magnitude,
                  "normal_displacement_real": real_part * normal,
                  "normal_velocity_abs": omega * ngs.sqrt((real_part * normal) ** 2
                                                          + (imag_part * normal) ** 2)}
        name = f"mode_{number:03d}_{_safe(mode.label)}"
        files.append(write_membrane_vtu(directory / name, state.mesh, fields,
                                        deformation=state.displacement))
    return files


def _safe(label: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in label).strip("_")


# -- plots --------------------------------------------------------------------------
def plot_modes(path: Path, vtu_files: list[Path], modes, columns: int = 4) -> None:
    """PNG of the lowest structural modes, coloured by |u.n| (pyvista, off-screen)."""
    import pyvista as pv

    pv.OFF_SCREEN = True
    count = len(vtu_files)
    if count == 0:
        return
    rows = (count + columns - 1) // columns
    plotter = pv.Plotter(off_screen=True, shape=(rows, min(columns, count)),
                         window_size=(300 * min(columns, count), 300 * rows))
    for k, (file, mode) in enumerate(zip(vtu_files, modes)):
        plotter.subplot(k // columns, k % columns)
        grid = pv.read(file)
        scale = 0.15 * float(np.ptp(grid.points[:, 0]))
        warped = grid.warp_by_vector("displacement_real", factor=scale)
        plotter.add_mesh(warped, scalars="normal_displacement_real", cmap="coolwarm",
                         show_scalar_bar=False)
        plotter.add_text(f"{mode.label}  {mode.freq_hz:.1f} Hz", font_size=10)
        plotter.view_isometric()
    plotter.screenshot(str(path))
    plotter.close()


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


def write_force_csv(path: Path, z_values, voltages, forces) -> None:
    """Long table voltage_v, z_m, force_n."""
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["voltage_v", "z_m", "force_n"])
        for voltage, row in zip(voltages, forces):
            for z, force in zip(z_values, row):
                writer.writerow([f"{voltage:.10g}", f"{z:.10g}", f"{force:.10g}"])


def write_json(path: Path, document: dict) -> None:
    path.write_text(json.dumps(document, indent=1, default=_json))
