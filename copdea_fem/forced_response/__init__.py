"""Forced harmonic response of the coupled FE model and the sound it radiates.

- :mod:`.run`: the ``copdea-fem response`` pipeline; :mod:`.files`: its result files.

The pipeline asks the study's engine for its forced problem
(:meth:`copdea_fem.fe.engines.Engine.forced_problem`) and drives it with the parts below
the engines: :mod:`copdea_fem.fe.forced.harmonic` (the voltage forcing, the hysteretic loss,
modal superposition over the coupled complex modes with a residual correction, and the
direct solve), :mod:`copdea_fem.fe.forced.radiation` (observation of the membrane velocity,
radiated and input power, Kirchhoff-Helmholtz / Rayleigh far field and SPL) and
:mod:`copdea_fem.fe.forced.problem`.  Each engine builds its forced problem below it:
:mod:`copdea_fem.fe.axisymmetric.forced` (the order m = 0, the only order a uniform
electrode excites) and :mod:`copdea_fem.fe.quadrant.forced` (the even-even symmetry sector
of the 3-D quadrant).
"""
