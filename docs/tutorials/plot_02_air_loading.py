"""
Air loading: dry against coupled
================================

How much the air lowers G1's frequencies: the same study in vacuo (``air.enabled:
false``) and coupled to the air in an infinite baffle (the axisymmetric engine, seconds
on a coarse mesh).
"""

# %%
from pathlib import Path

import matplotlib.pyplot as plt

import copdea_fem as cf

# the repository root (the tutorials run in docs/tutorials)
ROOT = next(path for path in (Path.cwd(), *Path.cwd().parents) if (path / "studies").is_dir())

coarse = {"geometry.frame": "baffle", "eigen.f_max": "700 Hz"}
dry = cf.solve(cf.load_study(ROOT / "studies/g1_z16_v2_quick.yaml",
                             {**coarse, "air.enabled": False}))
wet = cf.solve(cf.load_study(ROOT / "studies/g1_z16_v2_quick.yaml", coarse))

# %%
# Join the two tables on the label: the coupled solve's own ``dry_freq_hz`` (its dry
# partner on the same mesh) equals the dry solve's frequency.
table = wet.modes.query("kind == 'out-of-plane'").merge(
    dry.modes[["label", "freq_hz"]], on="label", suffixes=("", "_dry_solve"))
table[["label", "freq_hz", "dry_freq_hz", "freq_hz_dry_solve", "added_mass_ratio",
       "damping_ratio"]]

# %%
# The axisymmetric modes (m = 0) carry the largest added mass: (0,1) moves the most air.
figure, axis = plt.subplots(figsize=(6, 3.5))
axis.bar(table["label"], table["added_mass_ratio"])
axis.set_ylabel("added-mass ratio (f_dry/f)^2 - 1")
axis.set_title("G1, z = 16 mm, 2 kV, baffle")
figure.tight_layout()
