"""Result files of ``copdea-fem response`` (the list is in :mod:`.run`): CSV, JSON, PNG, VTU.

Staged through :func:`copdea_fem.folders.result_directory` like ``solve``'s files.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

AVERAGE_COLUMNS = ("freq_hz", "v_axial", "v_radial")
POINT_COLUMNS = ("freq_hz",) + tuple(f"v_{component}_q{i}" for i in (1, 2, 3)
                                     for component in ("axial", "radial"))
MODE_COLUMNS = ("label", "kind", "freq_hz", "freq_im_hz", "damping_per_mass",
                "membrane_energy_fraction")
#: modal_forcing.csv: the modal force per volt of a segment's input [N/(V sqrt(kg))]
MODAL_FORCING_COLUMNS = ("segment", "label", "freq_hz", "force_re", "force_im")


@dataclass
class ShapeAt:
    """A mode-like record for the revolved VTU writers of :mod:`copdea_fem.output`."""

    label: str
    freq_hz: float
    vector: np.ndarray          # order space coefficients [m per line]
    operators: object
    m: int = 0
    family: str = "cos"
    freq_im_hz: float = 0.0
    sector: object = None       # 3-D: the even-even symmetry sector
    orientation_deg: float = float("nan")   # deg; an operating shape has none (a mode's VTU field)
    orientation: float = float("nan")       # deg; not turned (the revolved writers' Mode.orientation)


def _plots(staging: Path, result, reduced) -> list[str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    study = result.problem.study
    setup, spectrum = reduced
    title = (f"{study.name}: FE forced response ({result.problem.engine}, {result.method}); z = "
             f"{1e3 * study.load.z:g} mm, V_b = {study.load.voltage / 1e3:g} kV, "
             f"frame {study.geometry.frame}")
    written = []
    fig, axes = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    for axis, fe, name, key in ((axes[0], result.average_axial, "axial", "average_axial"),
                                (axes[1], result.average_radial, "radial", "average_radial")):
        axis.plot(result.frequency_hz, 1e3 * fe, "k-", lw=1, label="FE (coupled)")
        if spectrum is not None:
            axis.plot(spectrum.frequency_hz, 1e3 * getattr(spectrum, key), "b--", lw=1,
                      label="reduced model (eq. 19)")
        for mode in result.modes:
            if mode.kind != "air" and mode.freq_hz <= result.frequency_hz.max():
                axis.axvline(mode.freq_hz, color="0.8", lw=0.8, zorder=0)
                axis.text(mode.freq_hz, 1.0, mode.label, transform=axis.get_xaxis_transform(),
                          ha="center", va="bottom", fontsize=7, color="0.4")
        axis.set_ylabel(f"{name} velocity [mm/s]")
        axis.legend(fontsize=8)
    axes[-1].set_xlabel("frequency [Hz]")
    fig.suptitle(title, fontsize=8)
    fig.tight_layout()
    fig.savefig(staging / "response_average.png", dpi=150)
    plt.close(fig)
    written.append("response_average.png")
    fig, axes = plt.subplots(3, 2, figsize=(9, 7), sharex=True)
    for i in range(3):
        for j, (values, name) in enumerate(((result.point_axial, "axial"),
                                            (result.point_radial, "radial"))):
            axes[i, j].plot(result.frequency_hz, 1e3 * values[:, i], "k-", lw=1)
            if spectrum is not None:
                other = spectrum.point_axial if name == "axial" else spectrum.point_radial
                axes[i, j].plot(spectrum.frequency_hz, 1e3 * other[:, i], "b--", lw=1)
            axes[i, j].set_ylabel(f"Q{i + 1} {name} [mm/s]", fontsize=8)
    for axis in axes[-1]:
        axis.set_xlabel("frequency [Hz]")
    fig.suptitle(title + " (FE solid, reduced dashed)", fontsize=8)
    fig.tight_layout()
    fig.savefig(staging / "response_points.png", dpi=150)
    plt.close(fig)
    written.append("response_points.png")
    fig, axis = plt.subplots(figsize=(7, 3.5))
    for j, (name, position) in enumerate(result.microphones):
        axis.plot(result.frequency_hz, result.spl_db[:, j], lw=1,
                  label=f"{name} ({', '.join(f'{v:g}' for v in position)}) m")
    axis.set_xlabel("frequency [Hz]")
    axis.set_ylabel("SPL [dB re 20 uPa]")
    method = result.far_field.split(":")[0].split(" over")[0]
    axis.set_title(f"{study.name}: SPL on the chirp's lines; far field {method}", fontsize=8)
    axis.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(staging / "spl.png", dpi=150)
    plt.close(fig)
    written.append("spl.png")
    return written


def _paraview(staging: Path, result) -> None:
    from copdea_fem.vtu import write_pvd
    coupled, forced = result.problem.coupled, result.problem.forced
    dry, state = coupled.membrane, result.problem.state
    driven = result.problem.sector
    shapes, pressures = [], []
    for f in result.peaks_hz:
        line = int(np.argmin(abs(result.frequency_hz - f)))
        x = result.solution(line)
        shapes.append(ShapeAt(f"ODS {f:.2f} Hz", f, dry.to_full(forced.membrane(x))[:, 0], dry,
                              sector=driven.shape_sector(dry)))
        pressures.append(forced.pressure(x))
    files, air = driven.write_shapes(staging, state, coupled, shapes, pressures)
    for paths, old, new, pvd in ((files, "mode_", "ods_", "ods.pvd"),
                                 (air, "air_", "air_ods_", "air_ods.pvd")):
        renamed = []
        for path in paths:
            target = path.with_name(path.name.replace(old, new, 1))
            path.rename(target)
            renamed.append(target)
        write_pvd(staging / pvd, renamed, list(result.peaks_hz))


def write_response(result, out_dir: Path, reduced=(None, None)) -> None:
    """Every file of the response into ``out_dir`` (staged, moved into place when complete)."""
    from copdea_fem.folders import result_directory
    from copdea_fem.output.tables import write_json
    from copdea_fem.reduced.io import write_csv
    from copdea_fem.study import dump_resolved

    study = result.problem.study
    f = result.frequency_hz
    with result_directory(out_dir, "response") as staging:
        write_csv(staging / "response_average.csv", AVERAGE_COLUMNS,
                  (f, result.average_axial, result.average_radial))
        write_csv(staging / "response_points.csv", POINT_COLUMNS,
                  (f,) + tuple(values[:, i] for i in range(3)
                               for values in (result.point_axial, result.point_radial)))
        write_csv(staging / "spl.csv", ("freq_hz",) + tuple(f"spl_{name}"
                                                           for name, _ in result.microphones),
                  (f,) + tuple(result.spl_db[:, j] for j in range(len(result.microphones))))
        if result.modes:
            write_csv(staging / "response_modes.csv", MODE_COLUMNS,
                      ([m.label for m in result.modes], [m.kind for m in result.modes],
                       [m.freq_hz for m in result.modes], [m.freq_im_hz for m in result.modes],
                       list(result.basis.damping_per_mass),
                       [m.membrane_energy_fraction for m in result.modes]))
        rows = result.modal_forcing
        write_csv(staging / "modal_forcing.csv", MODAL_FORCING_COLUMNS,
                  ([r.segment for r in rows], [r.label for r in rows],
                   [r.freq_hz for r in rows], [r.force.real for r in rows],
                   [r.force.imag for r in rows]))
        dump_resolved(study, staging / "study.resolved.yaml")
        document = {
            "engine": result.problem.engine,
            "excited": result.problem.sector.excited, "method": result.method,
            "far_field": result.far_field,
            "units": {"frequency": "Hz", "velocity": "m/s", "spl": "dB re 20 uPa",
                      "position": "m"},
            "microphones": {name: position.tolist() for name, position in result.microphones},
            "peaks_hz": result.peaks_hz, "lines": int(f.size),
            "loss_factor": study.membrane.loss_factor,
            "unknowns": int(result.problem.forced.size),
            "equilibrium_residual": result.problem.forced.equilibrium_residual,
            "timings_s": result.timings}
        if result.segments:
            document["segments"] = list(result.segments)
            document["modal_forcing_unit"] = "N/(V sqrt(kg))"
        if result.method in ("reduced", "reduced_modal"):
            document["reduced_basis"] = result.basis.summary()
        write_json(staging / "response.json", document)
        if study.output.plots:
            _plots(staging, result, reduced)
        if study.output.paraview and result.peaks_hz and not result.segments:
            _paraview(staging, result)      # segments: the driven part's shapes are not all
