"""The forced harmonic response of the coupled FE model: the sound it radiates and what a
vibrometer sees.

- :mod:`.run`: the ``copdea-fem response`` pipeline (the uniform electrode); :mod:`.files`:
  its result files; :mod:`.reduced_basis`: its rational Krylov basis;
- :mod:`.scan`: the FE forced response at a vibrometer's scan points for an electrode that
  may be imperfect (the synthetic export of ``copdea-fem synth --format uff``);
- :mod:`.observers`: what both drive (:class:`.observers.LineResponse`, a driven part's
  solution on the lines) and what observes it: the microphones
  (:class:`.observers.Microphones`) and the scan points (:class:`.observers.ScanPoints`).

One driver for both: the engine of the solve hands over what it drives -- the forced problem
of the uniform electrode (:meth:`copdea_fem.fe.engines.Engine.forced_problem`: the order
m = 0 on the axisymmetric engine, the even-even symmetry sector of the 3-D quadrant) or every
part of a solve with an electrode's forcing (:meth:`copdea_fem.fe.engines.Engine.driven_parts`,
:meth:`copdea_fem.fe.engines.Engine.electrode_forcing`) -- and the parts below the engines
solve it: :mod:`copdea_fem.fe.forced.harmonic` (the voltage forcing, the hysteretic loss,
modal superposition over the coupled complex modes with a residual correction, and the
direct solve), :mod:`copdea_fem.fe.forced.radiation` (observation of the membrane velocity,
radiated and input power, Kirchhoff-Helmholtz / Rayleigh far field and SPL) and
:mod:`copdea_fem.fe.forced.problem`.  Nothing here names an engine.
"""
