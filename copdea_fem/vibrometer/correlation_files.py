"""The files of ``copdea-fem correlate``: pairs.csv, comac.csv, mac.png, report.md.

Written only through :meth:`copdea_fem.api.CorrelateResult.write` (into its staging folder).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

#: pairs.csv's columns, in order (``fe_auto_mac``: the paired FE unit's largest MAC with a
#: rival unit at the measured channels, :mod:`copdea_fem.vibrometer.pairing`).
PAIR_COLUMNS = ("condition", "test_mode", "test_freq_hz", "test_damping_ratio", "label",
                "fe_freq_hz", "freq_error", "mac", "fe_auto_mac")


def _number(value: float, digits: int = 6) -> str:
    return "" if value is None or (isinstance(value, float) and math.isnan(value)) else \
        f"{value:.{digits}g}"


def write_pairs_csv(path: Path, correlations) -> Path:
    """One row per identified test mode of every condition (label empty when unpaired)."""
    with open(path, "w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(PAIR_COLUMNS)
        for correlation in correlations:
            for pair in correlation.pairs:
                writer.writerow([correlation.condition, pair.test_mode,
                                 _number(pair.test_freq_hz), _number(pair.test_damping_ratio),
                                 pair.label, _number(pair.fe_freq_hz),
                                 _number(pair.freq_error), _number(pair.mac, 4),
                                 _number(pair.fe_auto_mac, 4)])
    return path


def write_comac_csv(path: Path, correlations, scans) -> Path:
    """COMAC per channel: condition, node, point position [m], direction, comac."""
    with open(path, "w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(("condition", "channel", "node", "x_m", "y_m", "z_m", "direction_x",
                         "direction_y", "direction_z", "comac"))
        for correlation, scan in zip(correlations, scans):
            for channel, value in enumerate(correlation.comac):
                point = int(scan.channel_point[channel])
                writer.writerow([correlation.condition, channel, int(scan.nodes[point]),
                                 *(f"{v:.6g}" for v in scan.positions[point]),
                                 *(f"{v:.4g}" for v in scan.channel_direction[channel]),
                                 _number(float(value), 4)])
    return path


def plot_mac(path: Path, correlations) -> Path:
    """The MAC matrices (the unit MAC the pairing used), one panel per condition: test modes
    (frequency) against FE modes (label, frequency), pairs outlined.

    Drawn on matplotlib's Agg canvas, not through pyplot (as :mod:`copdea_fem.output.plots`).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    count = max(len(correlations), 1)
    widths = [max(4.0, 0.28 * len(c.fe_labels) + 2.0) for c in correlations] or [4.0]
    heights = [max(3.0, 0.28 * len(c.pairs) + 2.0) for c in correlations] or [3.0]
    figure = Figure(figsize=(max(widths), sum(heights)), dpi=100)
    FigureCanvasAgg(figure)
    for index, correlation in enumerate(correlations):
        axis = figure.add_subplot(count, 1, index + 1)
        matrix = correlation.unit_mac
        image = axis.imshow(matrix if matrix.size else np.zeros((1, 1)), vmin=0, vmax=1,
                            cmap="viridis", aspect="auto", interpolation="nearest")
        axis.set_xticks(range(len(correlation.fe_labels)))
        axis.set_xticklabels([f"{label} {freq:.0f}" for label, freq in
                              zip(correlation.fe_labels, correlation.fe_freq_hz)],
                             rotation=90, fontsize=7)
        axis.set_yticks(range(len(correlation.pairs)))
        axis.set_yticklabels([f"{p.test_mode}: {p.test_freq_hz:.1f} Hz"
                              for p in correlation.pairs], fontsize=7)
        column = {label: k for k, label in enumerate(correlation.fe_labels)}
        for row, pair in enumerate(correlation.pairs):
            if pair.label:
                axis.add_patch(Rectangle((column[pair.label] - 0.5, row - 0.5), 1, 1,
                                         fill=False, edgecolor="red", lw=1.2))
        axis.set_xlabel("FE mode (label, Hz)")
        axis.set_ylabel("test mode")
        axis.set_title(f"{correlation.condition}: MAC (pairs: subspace MAC), paired in red",
                       fontsize=9)
        figure.colorbar(image, ax=axis, fraction=0.03)
    figure.tight_layout()
    # zlib's fastest level: the same pixels, a few times faster to write than the default 6
    # (an FE column per mode: 116 columns make a 3448-pixel-wide PNG)
    figure.savefig(path, pil_kwargs={"compress_level": 1})
    return path


def indistinct_message(correlation) -> str:
    """What to say when the measured channels cannot tell the paired FE shapes from a rival
    (:meth:`copdea_fem.vibrometer.pairing.Correlation.indistinct_pairs`); "" when they can."""
    indistinct = correlation.indistinct_pairs()
    if not indistinct:
        return ""
    worst = max(indistinct, key=lambda pair: pair.fe_auto_mac)
    paired = sum(1 for pair in correlation.pairs if pair.label)
    return (f"{correlation.condition}: the measured channels cannot tell the FE's shapes "
            f"apart for {len(indistinct)} of {paired} pairs (the paired FE mode has a rival "
            f"within the window whose shape at the channels has MAC >= "
            f"{correlation.mac_min:g} with its own; worst: test mode {worst.test_mode} "
            f"{worst.label} vs {worst.fe_rival}, {worst.fe_auto_mac:.2f}): those labels are "
            "not decided by shape (pairs.csv column fe_auto_mac); measure more points")


def report_markdown(name: str, correlations) -> str:
    """report.md: per condition, the pairs and what frequency order alone would have said."""
    from copdea_fem.vibrometer.pairing import pair_by_frequency

    lines = [f"# Correlation: {name}", "",
             ("Identified test modes paired one-to-one with the FE's modes by shape (largest "
              "total MAC within the frequency window; a split pair (m,n)a/b compared as a "
              "two-dimensional subspace)."), ""]
    for correlation in correlations:
        paired = [p for p in correlation.pairs if p.label]
        errors = [p.freq_error for p in paired]
        rms = math.sqrt(sum(e * e for e in errors) / len(errors)) if errors else math.nan
        by_frequency = pair_by_frequency(correlation.test_freq_hz, correlation.fe_freq_hz,
                                         correlation.fe_labels, correlation.window)
        summary = (f"- {len(paired)} of {len(correlation.pairs)} test modes paired (window "
                   f"{100 * correlation.window:g} %, MAC >= {correlation.mac_min:g}); RMS "
                   "frequency error of the pairs: "
                   + ("-" if math.isnan(rms) else f"{100 * rms:.2f} %"))
        header = ("| test mode | f [Hz] | damping ratio | label | FE f [Hz] | error | MAC | "
                  "by frequency alone |")
        indistinct = correlation.indistinct_pairs()
        if indistinct:
            summary += "\n- " + indistinct_message(correlation)
        lines += [f"## {correlation.condition}", "", summary, "", header,
                  "|---|---|---|---|---|---|---|---|"]
        for pair, other in zip(correlation.pairs, by_frequency):
            lines.append(
                f"| {pair.test_mode} | {pair.test_freq_hz:.2f} | "
                f"{_number(pair.test_damping_ratio, 3) or '-'} | {pair.label or 'unpaired'} | "
                + (f"{pair.fe_freq_hz:.2f} | {100 * pair.freq_error:+.2f} % | {pair.mac:.3f}"
                   if pair.label else "- | - | -")
                + f" | {other or '-'}{' (differs)' if other != pair.label else ''} |")
        lines.append("")
    lines += ["![MAC](mac.png)", ""]
    return "\n".join(lines)


__all__ = ["PAIR_COLUMNS", "indistinct_message", "plot_mac", "report_markdown",
           "write_comac_csv", "write_pairs_csv"]
