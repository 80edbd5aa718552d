"""The ParaView files' plumbing that both engines' field samplers share.

- :mod:`.vtu`: the VTU writer (raw appended arrays) and .pvd collections;
- :mod:`.merge`: coincident points merged, quadrants unfolded, the air's two halves.

Below the engines: :mod:`copdea_fem.quadrant.fields` and
:mod:`copdea_fem.axisymmetric.fields` sample the fields, :mod:`copdea_fem.output`
(above the engines) writes a solve's folder; every name stays importable from
``copdea_fem.output``.
"""
