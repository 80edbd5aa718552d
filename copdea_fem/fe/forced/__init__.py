"""The forced harmonic response's parts that both engines share.

- :mod:`.problem`: what an engine's forced problem hands the pipeline
  (:class:`~.problem.OrderZero`, :class:`~.problem.DrivenSector`);
- :mod:`.harmonic`: the forced pencil, the direct solve and the modal basis with its
  residual correction;
- :mod:`.radiation`: observation of the membrane velocity, radiated power,
  Kirchhoff-Helmholtz / Rayleigh far field and SPL.

Below the engines: each engine builds its forced problem from these
(:mod:`copdea_fem.fe.axisymmetric.forced`, :mod:`copdea_fem.fe.quadrant.forced`), and the
``copdea-fem response`` pipeline above them (:mod:`copdea_fem.forced_response`) drives it.
"""
