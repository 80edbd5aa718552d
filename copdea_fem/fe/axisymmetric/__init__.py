"""The axisymmetric engine: the meridian (r, z) mesh, one 2-D problem per order m.

- :mod:`.meridian`: the meridian mesh; :mod:`.membrane`, :mod:`.prestress`: the membrane line
  and its equilibrium; :mod:`.air`, :mod:`.operators`: the order-m operators;
- :mod:`.modes`: classification and labels per order; :mod:`.engine`: the stages;
- :mod:`.forcing`, :mod:`.forced`: the forced response of the order m = 0;
- :mod:`.fields`: the fields revolved to 3-D for ParaView.
"""
