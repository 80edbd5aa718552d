"""The files of ``copdea-fem identify``: identified.csv, the stabilisation diagrams (PNG)
and the identified shapes as VTU on the scan grid.

Written into a staging folder by the identify results' ``write``
(:mod:`copdea_fem.api.measured_results`) and by ``identify FILE``
(:mod:`copdea_fem.vibrometer.export_identification`); split from
:mod:`copdea_fem.vibrometer.identification`, which finds the modes.
"""

from __future__ import annotations

import numpy as np

from copdea_fem.vibrometer.identification import (FREQUENCY_STABLE, NEW, STABLE,
                                                  StabilisationDiagram)

#: Columns of identified.csv.
IDENTIFIED_COLUMNS = ("condition", "test_mode", "freq_hz", "damping_ratio", "mpc")


def identified_rows(sets) -> list[dict]:
    """identified.csv's rows: one per mode of every :class:`IdentifiedSet`."""
    return [{"condition": item.condition, "test_mode": mode.test_mode,
             "freq_hz": mode.freq_hz, "damping_ratio": mode.damping_ratio, "mpc": mode.mpc}
            for item in sets for mode in item.modes]


def write_identified(folder, sets) -> None:
    """identified.csv, stabilisation_<condition>.png and shapes_<condition>/ (one VTU per
    mode on the scan grid and a ParaView collection shapes.pvd, "time" = test mode) in
    ``folder`` (a staging folder: the caller's ``write`` owns it)."""
    import csv
    from pathlib import Path

    from copdea_fem.vibrometer.identified import shape_meshes
    from copdea_fem.vtu import write_all, write_pvd

    folder = Path(folder)
    with open(folder / "identified.csv", "w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=IDENTIFIED_COLUMNS)
        writer.writeheader()
        for row in identified_rows(sets):
            writer.writerow({**row, "freq_hz": f"{row['freq_hz']:.6g}",
                             "damping_ratio": f"{row['damping_ratio']:.6g}",
                             "mpc": f"{row['mpc']:.4f}"})
    for item in sets:
        if item.diagram is not None:
            plot_stabilisation(folder / f"stabilisation_{item.condition}.png", item.diagram,
                               f"{item.condition}: {len(item.modes)} modes")
        if item.modes:
            shapes = folder / f"shapes_{item.condition}"
            shapes.mkdir()
            files = write_all(shapes, shape_meshes(item.scan, item.modes))
            write_pvd(shapes / "shapes.pvd", files, [m.test_mode for m in item.modes])


def plot_stabilisation(path, diagram: StabilisationDiagram, title: str = "") -> None:
    """PNG of the stabilisation diagram: every order's poles (o new, f frequency-stable,
    filled: stable), the chosen modes as vertical lines (dashed orange: the summed |H|'s
    peaks no mode explains), the mean |H| behind (log scale).

    Drawn on matplotlib's Agg canvas, not through pyplot (as :mod:`copdea_fem.output.plots`).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(10, 6), dpi=100)
    FigureCanvasAgg(figure)
    axis = figure.add_subplot(1, 1, 1)
    styles = {NEW: {"marker": "o", "facecolors": "none", "edgecolors": "0.6", "s": 10,
                    "label": "new"},
              FREQUENCY_STABLE: {"marker": "s", "facecolors": "none", "edgecolors": "tab:blue",
                                 "s": 12, "label": "frequency stable"},
              STABLE: {"marker": "o", "color": "tab:red", "s": 12,
                       "label": "stable (f, damping)"}}
    for state, style in styles.items():
        x = np.concatenate([f[s == state] for f, s in zip(diagram.frequencies, diagram.status)]
                           or [np.zeros(0)])
        y = np.concatenate([np.full(int(np.sum(s == state)), order)
                            for order, s in zip(diagram.orders, diagram.status)]
                           or [np.zeros(0)])
        axis.scatter(x, y, **style)
    for frequency, _ in diagram.chosen:
        axis.axvline(frequency, color="k", lw=0.6, alpha=0.5)
    for index, frequency in enumerate(diagram.unexplained_peaks):
        axis.axvline(frequency, color="tab:orange", lw=1.2, ls="--",
                     label="peak of the summed |H| without a mode" if index == 0 else None)
    axis.set_xlim(*diagram.band)
    axis.set_xlabel("frequency [Hz]")
    axis.set_ylabel("model order")
    # y given: the title sits at the axes' top (nothing is drawn above them) without
    # matplotlib's search of both axes' tick labels for room, 40 % of the drawing
    axis.set_title(title or f"stabilisation diagram: {len(diagram.chosen)} modes chosen",
                   y=1.0)
    axis.legend(loc="lower right", fontsize=8, framealpha=0.9)
    twin = axis.twinx()
    magnitude = np.maximum(diagram.mean_magnitude, 1e-300)
    twin.semilogy(diagram.band_frequencies, magnitude, color="0.3", lw=0.8)
    twin.set_ylabel("mean |H| over the channels [SI]")
    figure.savefig(path, pil_kwargs={"compress_level": 1})


__all__ = ["IDENTIFIED_COLUMNS", "identified_rows", "plot_stabilisation", "write_identified"]
