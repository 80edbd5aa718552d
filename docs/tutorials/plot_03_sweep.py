"""
A sweep with mode tracking
==========================

Fig. 11b of the paper, coarse: G1's dry modes at V_b = 2 kV as the disc moves from 0 to
18 mm (``studies/sweeps/coarse_fig11b.yaml``).  Each point continues from the previous
one, and modes are tracked by their shapes (MAC), so a line is one mode even where
frequencies cross.
"""

# %%
from pathlib import Path

import matplotlib.pyplot as plt

import copdea_fem as cf

# the repository root (the tutorials run in docs/tutorials)
ROOT = next(path for path in (Path.cwd(), *Path.cwd().parents) if (path / "studies").is_dir())

result = cf.sweep(ROOT / "studies/sweeps/coarse_fig11b.yaml")
table = result.table
table[["point", "load.z_m", "track", "label", "freq_hz", "mac_previous"]].head(10)

# %%
# One line per tracked out-of-plane mode.
figure, axis = plt.subplots(figsize=(6, 4))
for track, rows in table.query("kind == 'out-of-plane'").groupby("track_label"):
    axis.plot(1e3 * rows["load.z_m"], rows["freq_hz"], marker="o", ms=3, label=track)
axis.set_xlabel("disc displacement z [mm]")
axis.set_ylabel("frequency [Hz]")
axis.legend(fontsize=7, ncol=2)
figure.tight_layout()
