"""
Selective excitation: a split electrode and a model for control
===============================================================

One electrode over the whole membrane drives the axisymmetric order m = 0 only: the
pumping mode (0,1) and the (0,n).  Split it into eight 45-degree sectors, each with its own
AC voltage on the common 2 kV bias, and a drive can light the (2,1) and the (3,1) while
holding the pumping mode down (``copdea-fem excite``, docs/excitation.md).  Then the device
as a real LTI system for a control engineer (``copdea-fem statespace``), loaded in
python-control.  G1 at z = 16 mm, 2 kV, coupled with the air in a baffle, on the
axisymmetric engine's coarse mesh.
"""

# %%
import shlex
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import copdea_fem as cf

# the repository root (the tutorials run in docs/tutorials)
ROOT = next(path for path in (Path.cwd(), *Path.cwd().parents) if (path / "studies").is_dir())

# the coupled quick study with its electrode split into eight sectors, in a baffle
baffle = ["mesh.engine=axisymmetric", "geometry.frame=baffle"]
split = cf.load_study(ROOT / "studies/g1_segments_quick.yaml", baffle)
print([segment.name for segment in split.electrodes.segments])

# %%
# The drive that lights the (2,1) and the (3,1) together, 100 V peak per sector: each
# sector's amplitude and phase, and what every out-of-plane mode of the band does at its
# own frequency, in dB re the (2,1) (``-inf``: a mode the sectors cannot reach at all).
design = cf.excite(split, ["(2,1)", "(3,1)"], max_ac=100.0)
print(design.drive.round(2))
levels = design.selectivity
levels[np.isfinite(levels["level_db"])].round(1)

# %%
# What eight sectors cannot separate: the orders m and 8 - m share one drive pattern (the
# Fourier series of a sector drive), so the (6,1) comes with the (2,1) and the (5,1)
# with the (3,1); and the a/b members of a pair are one drive turned.
for line in design.design.inseparable:
    print(line)

# %%
# Feed the drive to ``response``: the line excite prints (``response_set.txt``) is a
# ``--set`` of the segments with their drive; the single electrode is the study without
# segments, driven by the same 100 V chirp.
line = design.set_lines()[0]
print(line[:100], "...")
designed = cf.response(cf.load_study(ROOT / "studies/g1_segments_quick.yaml",
                                     [*baffle, shlex.split(line)[1]]))
single = cf.response(cf.load_study(ROOT / "studies/g1_z16_v2_quick.yaml", baffle))

figure, (top, bottom) = plt.subplots(2, 1, figsize=(6.5, 5.5), sharex=True)
for result, name in ((single, "one electrode"), (designed, "designed drive")):
    top.semilogy(result.average["freq_hz"], 1e3 * result.average["v_axial"], label=name)
    bottom.plot(result.spl["freq_hz"], result.spl["spl_axis"], label=name)
for label in ("(0,1)", "(2,1)a", "(3,1)a", "(5,1)a", "(6,1)a"):
    frequency = design.design.freq_hz[design.design.labels.index(label)]
    top.axvline(frequency, color="0.8", lw=0.8, zorder=0)
    top.text(frequency, 1.0, label.rstrip("a"), transform=top.get_xaxis_transform(),
             ha="center", va="bottom", fontsize=7)
top.set_ylabel("mean axial |v| [mm/s]")
bottom.set_ylabel("SPL on the axis at 1 m [dB]")
bottom.set_ylim(-20, None)       # the designed drive's is round-off, far below
bottom.set_xlabel("frequency [Hz]")
top.legend(fontsize=8)
figure.tight_layout()

# %%
# The (2,1) and the (3,1) now respond where the one electrode cannot reach them, and the
# pumping mode (0,1) is gone; but the partners eight sectors cannot separate from them,
# the (6,1) and the (5,1), respond as strongly or more (their modal force per unit drive
# is larger): the peaks at 650 and 720 Hz.  More sectors, or sectors of unequal widths,
# move those partners out of the band.
#
# The orders m >= 1 radiate nothing onto the axis (their pressure changes sign around
# it), so the sound there is what the drive leaves of the order 0: the designed drive
# moves the membrane at the (2,1) and the (3,1) and stays quiet on the axis.
axis = np.interp([design.design.freq_hz[design.design.labels.index(label)]
                  for label in ("(0,1)", "(2,1)a", "(3,1)a")],
                 single.spl["freq_hz"], single.spl["spl_axis"])
print("one electrode, SPL on the axis at the (0,1), (2,1), (3,1) [dB]:", axis.round(1))
print("designed drive, highest SPL on the axis [dB]:",
      round(float(designed.spl["spl_axis"].max()), 1))

# %%
# The state space of the split device: inputs the eight sectors' AC voltages, outputs the
# velocity components at the points Q1-Q3 and each sector's motional current.  With
# python-control installed (``pip install copdea-fem[control]``), ``system`` is a
# ``control.StateSpace``.
import control  # noqa: E402

model = cf.statespace(split)
system = model.system
print(model.summary_lines()[0])
print("poles below 1 kHz:", int(np.sum(np.abs(control.poles(system).imag) < 2 * np.pi * 1e3)))

# its Bode plot: the axial velocity at Q2 (0 deg) per volt on the first sector, and that
# sector's own motional current (self-sensing)
axial = [name for name in system.output_labels if name.endswith("q2_0deg") and "z" in name][0]
current = system.output_labels[-len(system.input_labels)]
frequency = np.geomspace(100.0, 1000.0, 400)
rows = [system.output_labels.index(axial), system.output_labels.index(current)]
control.bode_plot(system[rows, 0], omega=2 * np.pi * frequency, Hz=True, dB=True,
                  title=f"{split.name}: Bode plot, input {system.input_labels[0]}")
