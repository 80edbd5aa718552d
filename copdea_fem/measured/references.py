"""Which node of a dataset 58 FRF is the measured point: the response or the reference.

An FRF ``H_ij`` (response at i, excitation at j) is written with ``rsp_node``/``rsp_dir``
(i) and ``ref_node``/``ref_dir`` (j).  A single-reference test is one of two layouts:

- roving response (a scanning vibrometer, a shaker): one reference, the responses move;
  the points are the response nodes;
- roving reference (an impact hammer moved over the structure, one accelerometer): one
  response, the references move; by Maxwell-Betti reciprocity ``H_ij = H_ji`` (a linear
  structure with a symmetric dynamic stiffness: Ewins, *Modal testing*, 2nd ed.,
  Sect. 2.7), the same FRFs as a roving response test with the accelerometer's place as
  reference, so the points are the reference nodes.

Several references and several responses (a poly-reference test) is refused: the
identification here fits one residue per channel and mode for one reference (a
single-reference modal model) and would mix the references' shapes.  A spectrum (function
type 12) has no reference: its points are its response nodes.
"""

from __future__ import annotations

import logging

from copdea_fem.measured.errors import MeasuredDataError

logger = logging.getLogger(__name__)

#: The two single-reference layouts (module notes).
ROVING_RESPONSE, ROVING_REFERENCE = "roving response", "roving reference"


def layout(records, where: str) -> str:
    """:data:`ROVING_RESPONSE` or :data:`ROVING_REFERENCE` of FRF records (objects with
    ``response_node``, ``response_direction``, ``reference_node``,
    ``reference_direction``, ``function_type``); the roving reference said in the log, a
    poly-reference set refused naming its references."""
    frfs = [r for r in records if r.function_type == 4]
    if not frfs:
        return ROVING_RESPONSE
    references = sorted({(r.reference_node, r.reference_direction) for r in frfs})
    responses = sorted({(r.response_node, r.response_direction) for r in frfs})
    if len(references) <= 1:
        return ROVING_RESPONSE
    named = ", ".join(f"node {node} dir {direction}" for node, direction in references[:12])
    more = f" and {len(references) - 12} more" if len(references) > 12 else ""
    if len(responses) == 1:
        node, direction = responses[0]
        logger.info("%s: roving reference (%d references, one response at node %d dir %d): "
                    "read by reciprocity H_ij = H_ji, the reference nodes as the points",
                    where, len(references), node, direction)
        return ROVING_REFERENCE
    raise MeasuredDataError(
        f"{where}: {len(references)} references ({named}{more}) with {len(responses)} "
        "responses (a poly-reference test) is not allowed; allowed: one reference (roving "
        "response) or one response (roving reference, read by reciprocity): export one "
        "reference's FRFs per file")


__all__ = ["ROVING_REFERENCE", "ROVING_RESPONSE", "layout"]
