"""The 3-D engine: the quadrant mesh of the device in its air, any frame.

- :mod:`.geometry`: the OCC shapes, the Netgen mesh and the mesh cache;
- :mod:`.engine`: the stages (mesh -> prestress -> dry and coupled modes per symmetry sector);
- :mod:`.forced`: the even-even symmetry sector of the quadrant, forced by the voltage;
- :mod:`.fields`: the membrane and air fields sampled for ParaView, quadrants unfolded.

The axisymmetric engine's counterparts are in :mod:`copdea_fem.fe.axisymmetric`.
"""
