"""Forced harmonic response of the coupled FE model and the sound it radiates (issue 15).

- :mod:`.harmonic`: the voltage forcing, the hysteretic loss, modal superposition over the
  coupled complex modes with a residual correction, and the direct solve (one order of the
  axisymmetric engine: m = 0, the only order a uniform electrode excites).
- :mod:`.radiation`: observation of the membrane velocity, radiated and input power,
  Kirchhoff-Helmholtz / Rayleigh far field and SPL.
- :mod:`.quadrant`: the same on the 3-D quadrant engine (the even-even symmetry sector).
- :mod:`.run`: the ``copdea-fem response`` pipeline; :mod:`.files`: its result files.
"""
