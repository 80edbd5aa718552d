r"""The operating shape of a drive of several inputs: the membrane's velocity at one frequency
as ParaView point data (``excite``'s ``operating_shape_<label>.vtu``).

Each driven part of the solve (an order m with its cos and sin families, a 3-D symmetry
sector) is forced by the drive ``[(weight, amplitude), ...]`` as the scan response forces it
(:func:`copdea_fem.forced_response.scan.driven_groups`: the FE's ``e^{-i omega t}``
forcing ``sum_k conj(a_k) f_k``), and solved on the one line by its modal path with the
static correction of the modes above the band and the paper's modal b/m
(:func:`copdea_fem.forced_response.scan.part_line_response`: what ``excite``'s modal model,
:mod:`.modal_inputs` eq. 1, and the scan response compute).  Each part's membrane solution
``x`` [m] is written by the engine's own mode writer
(:meth:`copdea_fem.fe.engines.Engine.output`: revolved on the axisymmetric engine, a
sector's field unfolded on the 3-D quadrant), all parts on the same points, and summed:

    u(x) = sum_parts factor_family x_part(x)                [m per volt of the input]
    v(x) = conj(-i omega u(x))                               [m/s, e^{+i omega t}]

the velocity in the physical convention of the FRFs (:mod:`.scan`), times the input's
volts.  Point data (float64, Cartesian components): ``velocity_real``,
``velocity_imag``, ``velocity_abs`` (``|v|``, the norm of the complex vector),
``normal_velocity_real``, ``normal_velocity_imag``, ``normal_velocity_abs`` (along the
prestressed membrane's normal) [m/s]; the points are those of the prestressed membrane.
"""

from __future__ import annotations

import numpy as np

from copdea_fem.study import StudyError

#: Point data names of the operating shape [m/s].
VELOCITY_FIELDS = ("velocity_real", "velocity_imag", "velocity_abs", "normal_velocity_real",
                   "normal_velocity_imag", "normal_velocity_abs")


def operating_shape_mesh(solution, study, drive, frequency_hz: float, damping_per_mass):
    """The :class:`~copdea_fem.vtu.VtuMesh` of the operating shape (module notes).

    Parameters
    ----------
    solution : copdea_fem.fe.SolveResult
        The solve of ``study``.
    study : Study
    drive : list of (weight, complex)
        Each input's drive weight and complex AC volts, ``e^{+i omega t}`` convention (as
        :func:`copdea_fem.forced_response.scan.scan_response`'s ``electrode``).
    frequency_hz : float
        The line [Hz], > 0.
    damping_per_mass : callable
        ``mode -> (b/m)`` [1/s] (as :func:`~copdea_fem.forced_response.scan.scan_response`'s).
    """
    from copdea_fem.forced_response.files import ShapeAt
    from copdea_fem.forced_response.scan import driven_groups, part_line_response
    from copdea_fem.vtu import VtuMesh

    engine, state = solution.engine, solution.state
    lines = np.array([float(frequency_hz)])
    shapes = []
    for part in engine.driven_parts(solution, study):     # an empty band: its static part
        operators = part.pencil.membrane
        for force, families in driven_groups(engine, state, part, drive):
            if not families:
                continue
            response, *_ = part_line_response(solution, study, part, force, lines,
                                              damping_per_mass)
            membrane = response.membrane() @ response.weights[0]
            full = operators.to_full(membrane[:, None])[:, 0]
            for family, factor in families:
                shapes.append(ShapeAt(f"ODS {frequency_hz:.2f} Hz", float(frequency_hz),
                                      factor * full, operators,
                                      m=0 if part.m is None else int(part.m), family=family,
                                      sector=part.sector))
    if not shapes:
        raise StudyError("operating shape: the drive forces no part of the solve; allowed: "
                         "a drive with a non-zero amplitude on an input")
    displacement = normal = points = cells = None
    for _, mesh in engine.output(state, shapes).mode_meshes(shapes):
        data = mesh.point_data
        shape = data["displacement_real"] + 1j * data["displacement_imag"]
        along = data["normal_displacement_real"] + 1j * data["normal_displacement_imag"]
        if displacement is None:
            displacement, normal = shape, along
            points, cells = mesh.points, mesh.cells[0]
        else:
            displacement, normal = displacement + shape, normal + along
    omega = 2 * np.pi * float(frequency_hz)
    velocity = np.conj(-1j * omega * displacement)
    normal_velocity = np.conj(-1j * omega * normal)
    fields = dict(zip(VELOCITY_FIELDS, (
        velocity.real, velocity.imag, np.linalg.norm(np.abs(velocity), axis=1),
        normal_velocity.real, normal_velocity.imag, np.abs(normal_velocity))))
    return VtuMesh(points, [(cells.type, cells.data)], point_data=fields)


__all__ = ["VELOCITY_FIELDS", "operating_shape_mesh"]
