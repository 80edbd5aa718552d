"""The model's side of a scan: the FE solved at the scan's operating point, its structural
modes sampled along the scan's channels (:mod:`copdea_fem.vibrometer.sampling`) and paired
with the identified modes (:mod:`copdea_fem.vibrometer.pairing`)."""

from __future__ import annotations

import logging

import numpy as np

from copdea_fem.vibrometer.pairing import (
    DEFAULT_MAC_MIN,
    DEFAULT_WINDOW,
    Correlation,
    FEShapes,
    correlate_shapes,
)
from copdea_fem.vibrometer.sampling import mode_shapes_at_scan

logger = logging.getLogger(__name__)

#: The FE modes a vibrometer's shapes are compared with: not the air's own modes.
STRUCTURAL_KINDS = ("out-of-plane", "in-plane", "pumping")


def fe_shapes(study, scan, *, solve=None) -> FEShapes:
    """The FE modes of ``study`` along the channels of ``scan``.

    Parameters
    ----------
    study : copdea_fem.study.Study
        The model at the scan's operating point (coupled with the air when
        ``air.enabled``; the band ``eigen.f_min..f_max`` should cover the scan's).
    scan : copdea_fem.measured.ScanData
    solve : callable, optional
        ``solve(study) -> SolveResult``; default :func:`copdea_fem.fe.run_solve` on the
        study's engine (:func:`copdea_fem.fe.engine_for`, resolved here once).

    Returns
    -------
    FEShapes
        Labels, frequencies [Hz] and velocity shapes (C, K) of the structural modes.
    """
    study = study.replace({"output.plots": False, "output.paraview": False})
    if solve is None:
        from copdea_fem.fe import engine_for, run_solve
        result = run_solve(study, engine=engine_for(study))
    else:
        result = solve(study)
    modes = [mode for mode in result.modes if mode.kind in STRUCTURAL_KINDS and mode.label]
    logger.info("FE: %d structural modes sampled at %d scan points", len(modes),
                scan.n_points)
    return FEShapes.from_modes(modes, mode_shapes_at_scan(result, modes, scan))


def correlate_identified(condition: str, identified, fe: FEShapes, *,
                         window: float = DEFAULT_WINDOW,
                         mac_min: float = DEFAULT_MAC_MIN, warn: bool = True) -> Correlation:
    """Pair identified modes (:class:`copdea_fem.vibrometer.identified.IdentifiedMode`) with the
    FE's sampled shapes (:func:`copdea_fem.vibrometer.pairing.correlate_shapes`); with
    ``warn``, a warning when the channels cannot tell a pair's FE shape from a rival's
    (:meth:`~copdea_fem.vibrometer.pairing.Correlation.indistinct_pairs`)."""
    from copdea_fem.vibrometer.correlation_files import indistinct_message

    identified = tuple(identified)
    shapes = (np.column_stack([mode.shape for mode in identified]) if identified
              else np.zeros((fe.shapes.shape[0], 0), dtype=complex))
    correlation = correlate_shapes([mode.freq_hz for mode in identified], shapes, fe,
                                   test_damping_ratio=[mode.damping_ratio for mode in identified],
                                   window=window, mac_min=mac_min, condition=condition)
    if warn and correlation.indistinct_pairs():
        logger.warning(indistinct_message(correlation))
    return correlation


__all__ = ["STRUCTURAL_KINDS", "correlate_identified", "fe_shapes"]
