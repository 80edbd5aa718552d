"""The bundled scan example (studies/measured_scan_example) cut down as a lab might export
it: its out-of-plane records only, a few lines, another band - copied into a test folder."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCAN_EXAMPLE = ROOT / "studies" / "measured_scan_example"


def truth_frequencies(f_min=150.0, f_max=850.0) -> np.ndarray:
    """The example's true modal frequencies [Hz] in the band (synth_truth.json: the FE's,
    written when the export was made)."""
    truth = json.loads((SCAN_EXAMPLE / "synth_truth.json").read_text())
    frequencies = [mode["freq_hz"] for mode in truth["conditions"]["z16_v2"]["modes"].values()]
    return np.array(sorted(f for f in frequencies if f_min <= f <= f_max))


def out_of_plane(scan):
    """The scan's z records only (a 1-D laser along the axis: one channel per point)."""
    keep = np.flatnonzero(np.abs(scan.channel_direction[:, 2]) > 0.99)
    return dataclasses.replace(scan, channel_point=scan.channel_point[keep],
                               channel_direction=scan.channel_direction[keep],
                               values=scan.values[keep])


def example_copy(folder, *, band=None, lines=None, z_only=False) -> Path:
    """The example copied into ``folder``/scan (its measured.yaml returned), its export cut
    to the out-of-plane records (``z_only``) and/or the first ``lines`` lines, its
    condition's band replaced by ``band`` ([f_low, f_high] Hz)."""
    from copdea_fem.measured import read_scan, write_scan

    target = Path(folder) / "scan"
    shutil.copytree(SCAN_EXAMPLE, target)
    if z_only or lines is not None:
        scan = read_scan(target / "z16_v2.uff")
        if z_only:
            scan = out_of_plane(scan)
        if lines is not None:
            scan = dataclasses.replace(scan, frequencies=scan.frequencies[:lines],
                                       values=scan.values[:, :lines])
        write_scan(target / "z16_v2.uff", scan)
    measured = target / "measured.yaml"
    text = measured.read_text()
    if band is not None or lines is not None:
        old = "  band:\n  - 150 Hz\n  - 850 Hz\n"
        assert old in text
        text = text.replace(old, "" if band is None else
                            f"  band:\n  - {band[0]} Hz\n  - {band[1]} Hz\n")
    measured.write_text(text)
    return measured
