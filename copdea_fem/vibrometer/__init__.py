"""Scanning-vibrometer scans: identify their modes, pair them with the FE's by shape.

The scans arrive read, in SI and in the model's frame (:class:`copdea_fem.measured.ScanData`,
from :func:`copdea_fem.measured.read_scan`); ``identification`` finds their modes
(``identified``: the modes and their shapes as a surface; ``given_modes``: a mode set's
modes from another program as the same test modes), ``sampling`` and
``model_shapes`` put the FE's modes on the scan's channels, ``pairing`` pairs the two.
"""
