"""modes.csv / modes.json, the force table and JSON documents."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from copdea_fem.folders import package_versions
from copdea_fem.study import Study, dump_resolved

MODE_COLUMNS = ("label", "m", "n", "kind", "freq_hz", "freq_im_hz", "damping_ratio",
                "membrane_energy_fraction", "modal_mass", "dry_freq_hz", "added_mass_ratio",
                "normal_fraction", "disc_fraction", "residual", "symmetry", "orientation_deg")


def mode_rows(modes, dry_frequencies: dict | None = None) -> list[dict]:
    """One row per mode with :data:`MODE_COLUMNS` (SI: Hz, kg).

    ``dry_frequencies`` maps a mode's position in ``modes`` to the frequency of
    its dry partner [Hz]; None means the modes are dry themselves.  Modes
    without a partner (air modes) get NaN for ``dry_freq_hz`` and
    ``added_mass_ratio``.
    """
    rows = []
    for index, mode in enumerate(modes):
        dry = mode.freq_hz if dry_frequencies is None else dry_frequencies.get(index, math.nan)
        rows.append({
            "label": mode.label, "m": mode.m, "n": mode.n, "kind": mode.kind,
            "freq_hz": mode.freq_hz, "freq_im_hz": mode.freq_im_hz,
            "damping_ratio": mode.damping_ratio,
            "membrane_energy_fraction": mode.membrane_energy_fraction,
            "modal_mass": mode.modal_mass, "dry_freq_hz": dry,
            "added_mass_ratio": (dry / mode.freq_hz) ** 2 - 1 if mode.freq_hz > 0 else 0.0,
            "normal_fraction": mode.normal_fraction, "disc_fraction": mode.disc_fraction,
            "residual": mode.residual,
            # parity about x = 0 and y = 0 on a quadrant mesh (copdea_fem.fe.symmetry), else ""
            "symmetry": mode.sector.name if mode.sector is not None else "",
            # the member's antinode line [deg, 0 <= . < 180/m] (copdea_fem.fe.modes), NaN: m = 0
            "orientation_deg": mode.orientation_deg})
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


def frequency_table(rows: list[dict]) -> str:
    """Plain-text table of the modes for the terminal: the rows of modes.csv
    (:func:`mode_rows`) but its unnamed air/PML modes (label ``air``); an enclosure's cavity
    modes (``cavity(m,n,p)``, kind ``air`` or not) are listed as modes.csv lists them."""
    lines = [f"{'label':>13} {'kind':>13} {'f [Hz]':>10} {'Im f [Hz]':>10} {'residual':>9}"]
    for row in rows:
        if row["label"] != "air":
            lines.append(f"{row['label']:>13} {row['kind']:>13} {row['freq_hz']:10.2f} "
                         f"{row['freq_im_hz']:10.3f} {row['residual']:9.1e}")
    return "\n".join(lines)


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
