"""Scanning-vibrometer data: read a UFF export, identify its modes, pair them with the FE.

``scan`` holds the data a UFF export carries, in SI and in the model's frame; the reader,
the identification and the correlation with the FE work on these objects.
"""
