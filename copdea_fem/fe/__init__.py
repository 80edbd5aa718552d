"""The FE core: the physics, both engines and the eigen step.

Shared physics at this level, one module per stage of the pipeline:

- :mod:`.materials` (eq. 20) and :mod:`.membrane` (the membrane energy, eqs. 2-7);
- :mod:`.prestress`: the nonlinear electro-hyperelastic equilibrium (Newton, load steps);
- :mod:`.linearise`: the tangent, mass and damping operators at that equilibrium;
- :mod:`.acoustics`, :mod:`.airbox`, :mod:`.ale`, :mod:`.coupled`: the air, its PML, the
  moving air mesh and the coupled membrane-air pencil (Sect. 3.1);
- :mod:`.symmetry`: the mirror-symmetry sectors of the quadrant;
- :mod:`.eigen`: the shift-invert band eigensolver; :mod:`.bands`: the band rules both
  engines share; :mod:`.modes`: classification and labels;
- :mod:`.forced`: the forced harmonic response's parts both engines share;
- :mod:`.fields`: the ParaView fields' plumbing both engines share;
- :mod:`.engines`: the engine interface, :mod:`.pipeline`: mesh -> prestress -> modes.

The engines: :mod:`.quadrant` (the 3-D quadrant mesh: any frame) and :mod:`.axisymmetric`
(the meridian (r, z) mesh, one 2-D problem per circumferential order m).

Everything that computes modes here is in the FE code fingerprint
(:data:`copdea_fem.fingerprint.FE_SOURCES`): a new file is covered without a list to edit.
"""
