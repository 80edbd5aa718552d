"""ParaView fields of the axisymmetric engine: the meridian's fields revolved to 3-D."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from copdea_fem.fe.axisymmetric.modes import order_harmonics
from copdea_fem.fe.fields import AirHalves, CornerPressure, PointMerge, jump_vertices
from copdea_fem.vtu import VtuMesh, membrane_mesh, pressure_point_data, safe_name, write_all


def revolution_angles(max_order: int, minimum: int = 72, per_wave: int = 8) -> np.ndarray:
    """Polar angles [rad] of a revolved output: ``minimum``, or ``per_wave`` per wavelength of
    the highest order."""
    count = max(minimum, per_wave * int(max_order))
    return 2 * np.pi * np.arange(count) / count


class RevolvedMembraneSampler:
    """The membrane surface of an axisymmetric result, revolved: points, triangles, fields.

    Radii are the exact sample points of :class:`copdea_fem.fe.axisymmetric.meridian.LineSampler`
    (shared element ends merged); a field of order m is ``f(r) cos m theta`` (or the
    sin family's turned copy) on every ring of points.
    """

    def __init__(self, state, max_order: int = 0, prestress_profiles: dict | None = None):
        self.state = state
        self.line = state.line()
        self._prestress_profiles = prestress_profiles
        radii = self.line.radii.ravel()
        self.radii, self._unique = np.unique(np.round(radii, 12), return_index=True)
        self.angles = revolution_angles(max_order)
        rr, tt = np.meshgrid(self.radii, self.angles, indexing="ij")
        self._cos, self._sin = np.cos(tt).ravel(), np.sin(tt).ravel()
        self._rings = rr.ravel()
        self.coordinates = np.column_stack([rr.ravel() * self._cos, rr.ravel() * self._sin,
                                            np.zeros(rr.size)])
        n_r, n_t = len(self.radii), len(self.angles)
        index = np.arange(n_r * n_t).reshape(n_r, n_t)
        nxt = np.roll(index, -1, axis=1)
        lower, upper = index[:-1], index[1:]
        lower_next, upper_next = nxt[:-1], nxt[1:]
        cells = np.concatenate([
            np.stack([lower, upper, upper_next], axis=-1).reshape(-1, 3),
            np.stack([lower, upper_next, lower_next], axis=-1).reshape(-1, 3)])
        # a ring at r = 0 (a membrane without a disc) is one point
        component = index.copy()
        component[self.radii <= 1e-12 * max(self.radii.max(), 1e-300)] = index[0, 0]
        self.merge = PointMerge.from_components(component.ravel())
        keep = self.merge.labels[cells]
        self.cells = keep[(keep[:, 0] != keep[:, 1]) & (keep[:, 1] != keep[:, 2])
                          & (keep[:, 0] != keep[:, 2])]
        self.coordinates = self.merge.reduce(self.coordinates)

    def profile(self, coefficient) -> np.ndarray:
        """Values of a CoefficientFunction at the sample radii: (n_r,) or (n_r, d)."""
        values = self.line.values(coefficient)
        values = values.reshape(-1, *values.shape[2:])
        return values[self._unique]

    def ring(self, values, factor) -> np.ndarray:
        """Radial values (n_r[, d]) times an angular factor (n_t,) -> the written points."""
        return self.merge.reduce(self._ring(values, factor))

    def _ring(self, values, factor) -> np.ndarray:
        """Radial values (n_r[, d]) times an angular factor (n_t,) -> (n_r n_t[, d])."""
        values = np.asarray(values)
        out = values[:, None] * factor[None, :] if values.ndim == 1 else \
            values[:, None, :] * factor[None, :, None]
        return out.reshape(-1, *values.shape[1:])

    def vector(self, radial, hoop, axial, m=0, family="cos", orientation=math.nan) -> np.ndarray:
        """Cartesian vectors (n, 3) of (u_r, u_theta, u_z) amplitudes of an order-m field
        (``orientation``: :func:`.modes.order_harmonics`)."""
        main, cross = order_harmonics(m, family, self.angles, orientation)
        u_r, u_t, u_z = (self._ring(radial, main), self._ring(hoop, cross),
                         self._ring(axial, main))
        return self.merge.reduce(np.column_stack([u_r * self._cos - u_t * self._sin,
                                                  u_r * self._sin + u_t * self._cos, u_z]))

    def prestress_profiles(self) -> dict:
        """The prestress fields (``state.fields()``: displacement, stretches, stresses,
        thickness, e_field, normal; SI) at the sample radii: name -> (n_r,) or (n_r, d).

        One evaluation of all of them, compiled (:meth:`ngsolve.CoefficientFunction.Compile`:
        the subexpressions they share, the material's energy partials, evaluated once):
        equal to the bit to one evaluation per field, and far faster.  Found once
        per sampler; a sampler made from another one (:func:`revolved_sampler`) takes them.
        """
        import ngsolve as ngs

        if self._prestress_profiles is None:
            fields = self.state.fields()
            values = self.profile(ngs.CF(tuple(fields.values())).Compile())
            values = values.reshape(len(values), -1)
            self._prestress_profiles, start = {}, 0
            for name, value in fields.items():
                size = value.dim
                self._prestress_profiles[name] = values[:, start] if size == 1 else \
                    values[:, start:start + size]
                start += size
        return self._prestress_profiles

    def prestress_displacement(self) -> np.ndarray:
        """The prestress displacement at the written points, Cartesian (n, 3) [m]."""
        u = self.prestress_profiles()["displacement"]
        return self.vector(u[:, 0], np.zeros(len(u)), u[:, 1])

    def prestress_fields(self) -> dict:
        """The prestress fields at the written points (prestress.vtu's point data, SI):
        vectors Cartesian (n, 3), scalars (n,)."""
        data = {}
        for name, values in self.prestress_profiles().items():
            if name in ("displacement", "normal"):
                data[name] = self.vector(values[:, 0], np.zeros(len(values)), values[:, 1])
            else:
                data[name] = self.ring(values, np.ones(len(self.angles)))
        return data


def write_revolved_mode_vtus(directory: Path, state, modes, sampler=None) -> list[Path]:
    """One .vtu per mode of the axisymmetric engine, revolved; fields as write_mode_vtus."""
    return write_all(directory, revolved_mode_meshes(state, modes, sampler))


def revolved_sampler(state, modes, sampler=None) -> RevolvedMembraneSampler:
    """``sampler`` if its angles resolve the highest order of ``modes``, else a finer one."""
    highest = max([mode.m for mode in modes], default=0)
    if sampler is None or len(sampler.angles) < len(revolution_angles(highest)):
        sampler = RevolvedMembraneSampler(
            state, highest, sampler.prestress_profiles() if sampler is not None
            and sampler.state is state else None)
    return sampler


def revolved_mode_meshes(state, modes, sampler=None):
    """``(file stem, VtuMesh)`` of each mode of :func:`write_revolved_mode_vtus`;
    ``sampler`` as the writer would choose it for ``modes`` (:func:`revolved_sampler`).

    Every mesh holds the same points (the deformed membrane) and triangles, the same
    arrays, so that a :class:`~copdea_fem.vtu.VtuWriter` encodes them once."""
    sampler = revolved_sampler(state, modes, sampler)
    deformed = sampler.coordinates + sampler.prestress_displacement()
    normal_profile = sampler.prestress_profiles()["normal"]
    for number, (mode, amplitude) in enumerate(zip(modes, amplitude_profiles(sampler, modes))):
        shape = [sampler.vector(amplitude[:, 0].real, amplitude[:, 1].real,
                                amplitude[:, 2].real, mode.m, mode.family, mode.orientation),
                 sampler.vector(amplitude[:, 0].imag, amplitude[:, 1].imag,
                                amplitude[:, 2].imag, mode.m, mode.family, mode.orientation)]
        normal = amplitude[:, 0] * normal_profile[:, 0] + amplitude[:, 2] * normal_profile[:, 1]
        main, _ = order_harmonics(mode.m, mode.family, sampler.angles, mode.orientation)
        normal_shape = sampler.ring(normal, main)
        omega = 2 * np.pi * abs(complex(mode.freq_hz, mode.freq_im_hz))
        fields = {"displacement_real": shape[0], "displacement_imag": shape[1],
                  "displacement_abs": np.linalg.norm(np.abs(shape[0] + 1j * shape[1]), axis=1),
                  "normal_displacement_real": normal_shape.real,
                  "normal_displacement_imag": normal_shape.imag,
                  "normal_velocity_abs": omega * np.abs(normal_shape)}
        yield (f"mode_{number:03d}_{safe_name(mode.label)}",
               VtuMesh(deformed, [("triangle", sampler.cells)], point_data=fields))


def amplitude_profiles(sampler, modes) -> list[np.ndarray]:
    """Each mode's complex amplitudes (a, b, c) at the sample radii of ``sampler``, an
    (n_r, 3) array per mode [m per unit of the mode vector].

    The real and imaginary parts of every mode of one order (one space) are sampled in one
    evaluation of all their amplitude CoefficientFunctions (the components of one tuple
    CoefficientFunction): equal to the bit to one evaluation per amplitude and part, in
    about a quarter of the time.
    """
    import ngsolve as ngs

    by_order: dict = {}
    for number, mode in enumerate(modes):
        by_order.setdefault(id(mode.operators), []).append(number)
    profiles = [None] * len(modes)
    for numbers in by_order.values():
        operators = modes[numbers[0]].operators
        functions, amplitudes = [], []
        for number in numbers:
            for part in (np.real(modes[number].vector), np.imag(modes[number].vector)):
                gf = ngs.GridFunction(operators.space)
                gf.vec.FV().NumPy()[:] = part
                functions.append(gf)                # alive while its functions are evaluated
                amplitudes.extend(operators.amplitudes(gf))
        values = sampler.profile(ngs.CF(tuple(amplitudes)))        # (n_r, 6 per mode)
        for k, number in enumerate(numbers):
            real, imag = values[:, 6 * k:6 * k + 3], values[:, 6 * k + 3:6 * k + 6]
            profiles[number] = real + 1j * imag
    return profiles


def write_revolved_air_vtus(directory: Path, operators, modes, pressures) -> list[Path]:
    """One .vtu per mode of the revolved air (:func:`revolved_air_meshes`)."""
    return write_all(directory, revolved_air_meshes(operators, modes, pressures))


def revolved_air_meshes(operators, modes, pressures, max_order: int | None = None):
    """``(file stem, VtuMesh)`` of each mode of the air of the axisymmetric engine,
    revolved (wedge cells); ``max_order``: the highest order of the modes written together
    (sets the angles; default: that of ``modes``).

    The meridian's vertices are revolved on the deformed meridian; as in
    :func:`copdea_fem.fe.quadrant.fields.write_air_vtus` the lower half gets its own copy of
    the vertices (the pressure jumps across the screens) and values are taken inside each
    element.
    Fields and cell data as there; a field of order m is ``p(r, z) cos m theta``
    (or the sin family's turned copy; a member of a pair split by an imperfection turned to
    its orientation, :func:`.modes.order_harmonics`).
    """
    import ngsolve as ngs

    if not operators or not modes:      # no mode in the band: no air file
        return
    by_order = {coupled.m: coupled for coupled in operators}
    mesh = operators[0].pressure_space.mesh
    corners = ngs.IntegrationRule([(1, 0), (0, 1), (0, 0)], [0.0] * 3)
    points = mesh.MapToAllElements(corners, ngs.VOL)
    halves = AirHalves(mesh, points, operators[0].mesh_motion,
                        split=jump_vertices(operators[0].pressure_space,
                                             len(mesh.ngmesh.Coordinates())))
    lower, in_pml, copy, used, count = (halves.lower, halves.in_pml, halves.copy, halves.used,
                                        halves.count)
    moved = halves.moved
    triangles = halves.renumber[copy]
    # the air of every mode is a large file: 36 angles, or 4 per wavelength
    if max_order is None:
        max_order = max([mode.m for mode in modes], default=0)
    angles = revolution_angles(max_order, 36, 4)
    n_t = len(angles)
    r, z = moved[used, 0], moved[used, 1]
    # a vertex on the axis (reference r = 0) is one point, not one per angle
    component = np.arange(len(used) * n_t).reshape(len(used), n_t)
    reference_r = np.abs(halves.reference[used, 0])
    on_axis = reference_r <= 1e-9 * reference_r.max()
    component[on_axis] = component[on_axis, :1]
    merge = PointMerge.from_components(component.ravel())
    xyz = merge.reduce(np.column_stack([(r[:, None] * np.cos(angles)).ravel(),
                                        (r[:, None] * np.sin(angles)).ravel(),
                                        np.repeat(z, n_t)])).astype(np.float32)
    step = np.arange(n_t)
    ring = triangles[:, :, None] * n_t                              # (el, 3, 1)
    cells = np.concatenate([ring + step, ring + (step + 1) % n_t], axis=1)   # (el, 6, n_t)
    # a wedge with a corner on the axis keeps its two (now equal) corner numbers: ParaView
    # reads it as the collapsed wedge it is
    cells = merge.labels[np.moveaxis(cells, 2, 1).reshape(-1, 6)]
    cell_data = {"pml": [np.repeat(in_pml.astype(np.int8), n_t)],
                 "lower_half": [np.repeat(lower.astype(np.int8), n_t)]}
    if halves.cavity.any():         # an enclosure's air: ParaView's Threshold on it
        cell_data["cavity"] = [np.repeat(halves.cavity.astype(np.int8), n_t)]
    readers: dict = {}          # id(pressure space) -> CornerPressure
    for number, (mode, pressure) in enumerate(zip(modes, pressures)):
        coupled = by_order[mode.m]
        space = coupled.pressure_space
        reader = readers.get(id(space))
        if reader is None:
            reader = readers[id(space)] = CornerPressure(space, points)
        vector = np.zeros(space.ndof, dtype=complex)
        vector[coupled.pressure_free] = pressure
        values = reader(vector)
        nodal = np.zeros(2 * count, dtype=complex)
        nodal[copy.ravel()] = values.ravel()
        main, _ = order_harmonics(mode.m, mode.family, angles, mode.orientation)
        field = merge.reduce((nodal[used][:, None] * main[None, :]).ravel())
        data = pressure_point_data(field)
        yield (f"air_{number:03d}_{safe_name(mode.label)}",
               VtuMesh(xyz, [("wedge", cells)], point_data=data, cell_data=cell_data))


class RevolvedOutput:
    """The axisymmetric engine's result fields for ParaView and the API, behind the engine
    interface (:meth:`copdea_fem.fe.axisymmetric.engine.AxisymmetricEngine.output`): the
    meridian's fields revolved.

    ``modes``: the structural modes written together; their highest order sets the angles
    of every mode's membrane and air (:func:`revolved_sampler`, :func:`revolved_air_meshes`),
    so one mode's grid equals its file.  The prestress is revolved on the coarsest angles.
    """

    symmetry = "orders"     # modes.json: one problem per azimuthal order m

    def __init__(self, state, modes=()):
        self.state = state
        self.modes = list(modes)
        self.max_order = max([mode.m for mode in self.modes], default=0)
        self._prestress = None
        self._sampler = None

    @property
    def prestress_sampler(self) -> RevolvedMembraneSampler:
        if self._prestress is None:
            self._prestress = RevolvedMembraneSampler(self.state)
        return self._prestress

    @property
    def sampler(self) -> RevolvedMembraneSampler:
        """The sampler of the mode files (angles resolving the highest order)."""
        if self._sampler is None:
            self._sampler = revolved_sampler(self.state, self.modes, self.prestress_sampler)
        return self._sampler

    def prestress_mesh(self):
        """The :class:`~copdea_fem.vtu.VtuMesh` of prestress.vtu (the prestress
        fields, deformed)."""
        sampler = self.prestress_sampler
        return membrane_mesh(sampler, sampler.prestress_fields(),
                             sampler.prestress_displacement())

    def mode_meshes(self, modes):
        """``(file stem, VtuMesh)`` of each mode's membrane file
        (:func:`revolved_mode_meshes`)."""
        return revolved_mode_meshes(self.state, modes, self.sampler)

    def air_meshes(self, operators, modes, pressures):
        """``(file stem, VtuMesh)`` of each mode's air file (:func:`revolved_air_meshes`)."""
        highest = max([self.max_order] + [mode.m for mode in modes])
        return revolved_air_meshes(operators, modes, pressures, max_order=highest)
