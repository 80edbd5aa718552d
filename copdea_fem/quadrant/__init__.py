"""The 3-D engine's forced response and output sampling (:mod:`copdea_fem.engine3d`).

- :mod:`.forced`: the even-even symmetry sector of the quadrant, forced by the voltage;
- :mod:`.fields`: the membrane and air fields sampled for ParaView, quadrants unfolded.

The axisymmetric engine's counterparts are :mod:`copdea_fem.axisymmetric.forced` and
:mod:`copdea_fem.axisymmetric.fields`.
"""
