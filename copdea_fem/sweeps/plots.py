"""The sweep plot (Fig. 11 style): frequency against the swept parameter."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np

from copdea_fem.sweeps.spec import Sweep


def plot_sweep(path: Path, sweep: Sweep, rows: list[dict], max_panels: int = 12) -> None:
    """Fig. 11 style: frequency vs the first axis, one labelled line per tracked mode.

    Tracks that have one of ``output.plot_kinds`` at some point are drawn.

    Other axes give one panel per combination of their values (at most
    ``max_panels``).  Pairs are drawn as one line at the mean of their members.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x_axis = sweep.axes[0]
    others = sweep.axes[1:]
    combos = list(itertools.product(*(range(len(a.values)) for a in others)))[:max_panels]
    columns = min(3, len(combos))
    figure_rows = math.ceil(len(combos) / columns)
    figure, panels = plt.subplots(figure_rows, columns, figsize=(5.2 * columns,
                                                                  4.2 * figure_rows),
                                  squeeze=False)
    # a track is drawn whole if it has the plotted kind at one point at least (through a
    # veering its kind may change, e.g. (0,3) -> in-plane)
    shown_tracks = {row["track"] for row in rows
                    if row.get("status") == "ok" and row["kind"] in sweep.plot_kinds}
    ok = [row for row in rows if row.get("status") == "ok" and row["track"] in shown_tracks]
    colours = plt.get_cmap("tab20")
    for number, combo in enumerate(combos):
        axes = panels[number // columns][number % columns]
        wanted = {a.column(): a.values[i] for a, i in zip(others, combo)}
        tracks: dict[int, list] = {}
        for row in ok:
            if all(row[c] == v for c, v in wanted.items()):
                tracks.setdefault(row["track"], []).append(row)
        ends = []   # (x, y, label, colour) of each line's right end
        for track, members in sorted(tracks.items()):
            by_x: dict = {}
            for row in members:
                by_x.setdefault(row[x_axis.column()], []).append(row["freq_hz"])
            xs = sorted(by_x)
            ys = [float(np.mean(by_x[x])) for x in xs]
            shown = [x_axis.display(x) for x in xs]
            colour = colours(track % 20)
            axes.plot(shown, ys, "o-", color=colour, markersize=3.5, linewidth=1.2)
            ends.append((shown[-1], ys[-1], members[0]["track_label"], colour))
        _label_line_ends(axes, ends)
        axes.set_xlabel(x_axis.label())
        axes.set_ylabel("natural frequency [Hz]")
        title = ", ".join(f"{a.key} = {a.format(a.values[i])}"
                          for a, i in zip(others, combo)) or sweep.name
        axes.set_title(f"{title} ({sweep.model})", fontsize=9)
        axes.grid(alpha=0.3)
        axes.margins(x=0.12)
    for number in range(len(combos), figure_rows * columns):
        panels[number // columns][number % columns].axis("off")
    figure.tight_layout()
    figure.savefig(path, dpi=130)
    plt.close(figure)


def _label_line_ends(axes, ends, min_gap_fraction: float = 0.028) -> None:
    """Write each line's label at its right end, nudged apart where ends crowd.

    Labels ending at the same x are spread upwards to at least
    ``min_gap_fraction`` of the frequency range (about one 7-pt text line on
    the default figure).
    """
    if not ends:
        return
    low, high = axes.get_ylim()
    gap = min_gap_fraction * (high - low)
    by_x: dict = {}
    for x, y, label, colour in ends:
        by_x.setdefault(x, []).append((y, label, colour))
    for x, group in by_x.items():
        placed = -math.inf
        for y, label, colour in sorted(group, key=lambda item: item[0]):
            text_y = max(y, placed + gap)
            placed = text_y
            axes.annotate(label, (x, text_y), xytext=(4, 0), textcoords="offset points",
                          fontsize=7, color=colour, va="center")
