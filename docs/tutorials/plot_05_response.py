"""
Forced response and sound pressure level
========================================

The paper's forced-response case (Figs 12b and 14): G1 at z = 16 mm, V_b = 2 kV, the
disc on its spring, in a baffle, driven by the 100 V chirp from 0 to 1 kHz; the
coupled FE gives the membrane's average velocity and the sound pressure level at a
microphone 1 m in front (coarse mesh here).
"""

# %%
from pathlib import Path

import matplotlib.pyplot as plt

import copdea_fem as cf

# the repository root (the tutorials run in docs/tutorials)
ROOT = next(path for path in (Path.cwd(), *Path.cwd().parents) if (path / "studies").is_dir())

coarse = {"mesh.membrane_size": "6 mm", "mesh.order": 2, "mesh.pressure_order": 1,
          "mesh.air_size": "35.5 mm"}
response = cf.response(cf.load_study(ROOT / "studies/g1_z16_v2_response.yaml", coarse))
print("peaks [Hz]:", response.peaks_hz)
response.modes.query("kind != 'air'")

# %%
# The average axial velocity of the membrane (the measured quantity of Fig. 12) and the
# SPL at the microphone ``axis`` (dB re 20 uPa).
average, spl = response.average, response.spl
figure, (top, bottom) = plt.subplots(2, 1, figsize=(6, 5), sharex=True)
top.semilogy(average["freq_hz"], 1e3 * average["v_axial"])
top.set_ylabel("v_axial [mm/s]")
bottom.plot(spl["freq_hz"], spl["spl_axis"])
bottom.set_ylabel("SPL at 1 m [dB]")
bottom.set_xlabel("frequency [Hz]")
figure.tight_layout()
