"""
A diagnosis on measured data
============================

``studies/measured_example`` holds resonances and average spectra of G1 at five operating
points, made with the air's added mass and the spring's own mass on; the base model has
neither.  ``diagnose`` finds which catalogued effects the model lacks, in order of
importance, and fits their parameters.
"""

# %%
from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd

import copdea_fem as cf

# the repository root (the tutorials run in docs/tutorials)
ROOT = next(path for path in (Path.cwd(), *Path.cwd().parents) if (path / "studies").is_dir())

diagnosis = cf.diagnose(ROOT / "studies/measured_example/measured.yaml")
print(diagnosis.verdict)
print("missing:", diagnosis.missing_effects)

# %%
# The steps of the search: each accepted effect and the frequency gap it leaves.
pd.DataFrame(diagnosis.document["history"])[["step", "action", "effects", "gap_after"]]

# %%
# Measured against model frequencies, before and after the missing effects are added.
pairs = []
for condition, data in diagnosis.document["per_condition"].items():
    for stage in ("before", "after"):
        for pair in data.get(stage, {}).get("pairs", []):
            pairs.append({"condition": condition, "stage": stage, **pair})
pairs = pd.DataFrame(pairs)
figure, axis = plt.subplots(figsize=(5, 4.5))
for stage, rows in pairs.groupby("stage"):
    axis.scatter(rows["measured_hz"], rows["model_hz"], s=12, label=stage)
top = float(pairs[["measured_hz", "model_hz"]].max().max())
axis.plot([0, top], [0, top], color="grey", lw=0.8)
axis.set_xlabel("measured [Hz]")
axis.set_ylabel("model [Hz]")
axis.legend()
figure.tight_layout()
