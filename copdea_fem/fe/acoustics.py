r"""Air around the membrane: radial PML, pressure-jump space and forms (Sect. 3.1.2, eq. 8).

Pure functions: they set the PML on a mesh, build the pressure space and return
NGSolve bilinear-form integrands; they never read files, assemble or solve.
Regions are those of :mod:`copdea_fem.fe.quadrant.geometry` (volumes ``air_upper``,
``air_lower``, ``pml_upper``, ``pml_lower``; plane faces ``membrane``, ``disc``,
``frame``, ``aperture``, ``pml_plane``; spheres ``interface``, ``outer``).

Time convention and signs
-------------------------
Time-harmonic fields are ``Re{x e^{-i omega t}}`` -- NGSolve's convention, in
which a complex stretch with positive imaginary part damps the *outgoing* wave
``e^{+ikr}/r`` (``k = omega/c_a``).  The eigenvalue ``omega^2`` of a radiating
mode therefore has ``Im omega < 0``; its natural frequency is ``Re omega/2 pi``
and ``-Im omega/|omega|`` its radiation damping ratio zeta (loss factor 2 zeta).
Textbook impedances written for ``e^{+j omega t}`` appear here complex-conjugated:
pulsating sphere ``Z = rho c (-ika)/(1 - ika)``, baffled piston
``Z = rho c S [R1(2ka) - i X1(2ka)]``.

The plane z = 0 carries the *screens* (membrane, disc, frame) with the normal
``n = e_z`` pointing to the ``+`` side (z > 0, ``air_upper``); ``p+``/``p-`` are
the pressures on the upper/lower faces and ``[p] = p+ - p-``.

Strong form (eq. 8, corrected)
------------------------------
In the air (and, complex-stretched, in the PML), with ``u`` the membrane
displacement [m] and ``p`` the acoustic pressure [Pa]::

    -div((1/rho_a) grad p) - omega^2/(rho_a c_a^2) p = 0         in air and PML
    n . grad p+ = n . grad p- = -rho_a n . u_tt = rho_a omega^2 u . n   on the screens
    p continuous across the open part of the plane (aperture, pml_plane)
    p = 0 on ``outer`` (end of the unbounded PML, see :func:`radial_pml`)

Eq. (8) as printed has ``rho_a`` on the wrong side (``rho_a n.grad p`` is not an
acceleration); Euler's equation ``rho_a u_tt = -grad p`` puts it as above.  With
one normal ``n`` for both faces the two face conditions are the same; the
paper's opposite sign for ``p_i`` is the same condition written with the
inner face's own outward normal.  A rigid screen (frame, held disc) has
``u . n = 0``: homogeneous Neumann data on both faces, eq. (8) lines 4-5.
The air pushes the membrane with the traction ``-[p] n`` (upper air pushes down
with ``p+``, lower air pushes up with ``p-``), eq. (2) with ``p_delta = [p]``.

Weak form
---------
Multiply by a test pressure ``p'`` (one value per face on the screens) and
integrate by parts in the upper half (outward normal ``-n`` on the screens) and
the lower half (outward normal ``+n``)::

    k_a(p, p') - omega^2 m_a(p, p') + omega^2 c(u, p') = 0                  (A1)
    k_a(p, p') = int (1/rho_a) grad p . grad p' dx
    m_a(p, p') = int 1/(rho_a c_a^2) p p' dx
    c(u, p')   = int_screens [p'] (u . n) ds

and the membrane equation with the traction ``-[p] n`` (test ``u'``)::

    k_s(u, u') + c(u', p) - omega^2 m_s(u, u') = 0                           (A2)

In matrices, ``x = (u, p)``::

    [ K_s  C^T ] x = omega^2 [ M_s   0  ] x                                   (A3)
    [ 0    K_a ]             [ -C   M_a ]

a generalized eigenproblem *linear in omega^2* because the PML stretch is
frequency independent.  ``K_s, M_s`` are real symmetric; ``K_a, M_a`` are
complex symmetric (not Hermitian) once the PML is set, real symmetric without
it; the coupled ``A``, ``B`` are non-symmetric.  The left eigenvector for the
eigenvalue ``lambda = omega^2`` is ``y = (lambda u, p)``: ``A^T y = lambda B^T y``.
Incompressible-air check: for ``c_a -> inf`` (and no PML) (A1) gives
``p = -omega^2 K_a^-1 C u`` and (A2) becomes
``K_s u = omega^2 (M_s + C^T K_a^-1 C) u`` -- the added mass ``C^T K_a^-1 C`` is
positive semi-definite, so air loading lowers every frequency.

Pressure-jump space
-------------------
``p`` is one H1 field on all air + PML volumes.  A second H1 field ``q`` lives
on the lower half (``air_lower|pml_lower``) but keeps only its degrees of
freedom on the screen faces (compressed; zero on the open part of the plane and
on ``outer``).  Then::

    p_upper = p,   p_lower = p + q,   [p] = p+ - p- = -q   on the screens.

With the same element basis for both fields (same orders everywhere) the map
``(p, q) -> (p_upper, p_lower)`` is a bijection onto the H1 fields that are
continuous except across the screens: ``q`` only has degrees of freedom that
``p`` shares between the halves.  A ``q`` on the whole lower half would repeat
``p``'s lower interior DOFs and the system would be singular.

Enclosure (a rigid cavity under the membrane)
---------------------------------------------
With an enclosure the air inside it (volume ``cavity``, sealed to the membrane's rim,
walls ``enclosure`` rigid) is the lower side of the membrane and disc, and the pressure
jumps across its walls too (a rigid wall of no thickness between the cavity and the
outside air).  ``q`` then lives in the cavity instead of the lower half and keeps its
degrees of freedom on the cavity's screens and walls (:func:`enclosure_screen_faces`;
zero on the ``vent``, where the cavity opens to the outside air)::

    p_outside = p,   p_cavity = p + q,   [p] = -q on membrane, disc

At a DOF on a wall the outside and inside values are ``p`` and ``p + q``: the bijection
above still holds.  Where a frame reaches beyond the enclosure's rim (a cylinder or bowl
under the square frame) the frame separates the outside halves too: a third field
``q_o`` on the lower half keeps its DOFs on those frame faces (``outside_jump``), and
``p_lower = p + q_o``; its DOFs on the rim circle, where the frame, the wall and the
three airs meet, make three unknowns for the three values.  Without the outside air
(``vacuum_above``) ``p = 0`` on the screens (the vacuum above them) and the cavity's
pressure there is ``q``.  A pressure is a tuple ``(p, q)`` or ``(p, q, q_o)``;
:func:`region_pressures` says which sum is the pressure of which volume.

Frames: ``square`` and ``none`` leave the plane open outside the frame
(``aperture`` and ``pml_plane`` continuous).  ``baffle`` makes the frame the
whole plane inside the air sphere; we continue the baffle through the PML
(``pml_plane`` is a screen too): the radial stretch maps the plane z = 0 onto
itself, so a rigid plane is compatible with the PML, and the model then is the
infinite baffle of the textbook piston; stopping the baffle at r = R would
add an edge diffraction that the closed form does not have.
"""

from __future__ import annotations

#: The air inside an enclosure (the 3-D and meridian meshes); its walls are the boundary
#: ``enclosure``, its vent ``vent``.
CAVITY = "cavity"
UPPER = "air_upper|pml_upper"
LOWER = "air_lower|pml_lower"
AIR_AND_PML = "air_upper|air_lower|pml_upper|pml_lower"
PML_REGIONS = "pml_upper|pml_lower"
OUTER = "outer"
PLANE_NORMAL = (0.0, 0.0, 1.0)   # n: unit normal of the screens, pointing to the + (upper) side

#: Strength ``b`` of the unbounded PML profile (see :func:`radial_pml`).
#: Chosen by a scan on the pulsating sphere (monopole, the hardest case) in the
#: study's proportions (R = 3.5 a, 0.5 a shell, one element across it, PML
#: order 3, p = 0 on ``outer``); error of the radiation impedance at
#: 100 / 200 / 500 / 1000 Hz:  b = 5: 3.7 / 1.3 / 0.18 / 0.10 %;
#: b = 7: 1.8 / 0.41 / 0.11 / 0.17 %;  b = 10: 0.6 / 0.6 / 0.8 / 1.0 %
#: (too steep a decay for one element at order 3; at order 4 b = 10 gives
#: 0.6 / 0.05 / 0.05 / 0.07 % but the factorisation costs 3.5x).
PML_STRENGTH = 7.0

#: Polynomial order added to ``pressure_order`` in the PML elements: the
#: geometry puts about one element across the 0.5 r_o shell.  Baffled piston
#: (9 mm membrane mesh ... 6 mm) impedance error with PML order 2: 1.4-2 %,
#: with order 3: 0.02-0.35 %.  Factorising the default square-frame air (4 mm membrane
#: mesh) costs a little more at PML order 3 than at 2, and 3.5x that at 4.
PML_EXTRA_ORDER = 1


def has_cavity(mesh) -> bool:
    """Whether ``mesh`` holds the air of an enclosure (the volume :data:`CAVITY`)."""
    return CAVITY in mesh.GetMaterials()


def jump_side(mesh) -> str:
    """Volumes where the pressure is ``p + q`` (:func:`pressure_space`): the cavity when the
    mesh has an enclosure (the outside air is then all ``p``), else the lower half."""
    return CAVITY if has_cavity(mesh) else LOWER


def pressure_regions(mesh) -> list[tuple[str, str, bool]]:
    """``(air volumes, PML volumes, with q)`` of each side of the screens (module doc):
    ``p`` on the first, ``p + q`` where ``with q``; names of volumes the mesh lacks are left
    out ('' = none)."""
    present = set(mesh.GetMaterials())

    def keep(pattern):
        return "|".join(name for name in pattern.split("|") if name in present)

    if has_cavity(mesh):
        return [(keep("air_upper|air_lower"), keep(PML_REGIONS), False), (CAVITY, "", True)]
    return [(keep("air_upper"), keep("pml_upper"), False),
            (keep("air_lower"), keep("pml_lower"), True)]


def enclosure_screen_faces(frame: str, outside: bool = True) -> str:
    """Faces across which the pressure may jump with an enclosure (:func:`screen_faces`).

    ``q`` lives in the cavity: the membrane and disc on its top; the frame over it; the
    walls (``enclosure``) where outside air lies beyond them (frame none, circle, square).
    ``outside`` false (only the cavity's air): ``membrane|disc``, where ``p`` is held at 0
    (the vacuum above) and ``q`` carries the cavity's pressure (:func:`pressure_space`).
    """
    if not outside:
        return "membrane|disc"
    if frame == "baffle":
        return "membrane|disc|frame"
    return "membrane|disc|frame|enclosure"


def screen_faces(frame: str) -> str:
    """Faces across which the pressure may jump, as a region pattern.

    Parameters
    ----------
    frame : {"square", "circle", "baffle", "none"}
        ``study.geometry.frame``.

    Returns
    -------
    str
        ``"membrane|disc|frame"``; plus ``"|pml_plane"`` for ``baffle`` (the
        baffle continues into the PML, see module doc); ``"membrane|disc"`` for
        ``none``.  Missing names (no disc when r_i = 0) match nothing.
    """
    if frame == "baffle":
        return "membrane|disc|frame|pml_plane"
    if frame in ("square", "circle"):
        return "membrane|disc|frame"
    if frame == "none":
        return "membrane|disc"
    raise ValueError(f"geometry.frame = {frame!r} is not allowed; allowed: square, circle, "
                     "baffle, none")


PLANE_FACES = ("membrane", "disc", "frame", "aperture", "pml_plane")
#: Faces of an enclosure: its rigid walls (a screen when outside air lies beyond them)
#: and its vent (open: the pressure is continuous).
ENCLOSURE_FACES = ("enclosure", "vent")


def open_plane_faces(screens: str) -> str:
    """Plane faces (of ``aperture``, ``pml_plane``) not in ``screens``: pressure continuous
    there."""
    named = set(screens.split("|"))
    return "|".join(face for face in ("aperture", "pml_plane") if face not in named)


def radial_pml(domain_radius: float, pml_thickness: float, strength: float = PML_STRENGTH,
               profile: str = "unbounded"):
    r"""Frequency-independent radial complex stretch of the shell R < r < R + t.

    The point ``x`` (``r = |x| > R``) maps to ``x~ = x r~/r`` with
    ``r~ = r + i beta(r)``:

    - ``"unbounded"`` (default): ``beta = b t ln(t / (R + t - r))``.  An outgoing
      wave ``e^{ikr~}`` has modulus ``(1 - s/t)^{k b t}`` at depth ``s = r - R``:
      it reaches zero at the outer sphere for *every* wavenumber ``k``, so one
      fixed stretch serves the whole band (the frequency-independent form of
      the unbounded absorbing function of Bermudez et al., JCP 223 (2007) 469).
      Use with ``p = 0`` on ``outer`` (see :func:`pressure_space`).
    - ``"constant"``: ``beta = b (r - R)``, i.e. NGSolve's
      ``pml.Radial(rad=R, alpha=1j*b)``.  The round-trip reflection off the
      outer sphere is ``exp(-2 k b t)``: with t = 0.5 r_o = 17.75 mm it needs
      ``b > 100`` at 100 Hz (k t = 0.03), a decay no coarse mesh resolves at
      1 kHz.  Measured with b = 10: impedance error 60 % (pulsating sphere)
      and 35 % (baffled piston) at 200 Hz; flat-membrane (0,1) frequency
      within 0.01 % of the unbounded profile's but its radiation damping
      40 times smaller.  Kept for comparison.

    Parameters
    ----------
    domain_radius : float
        Radius R of the air sphere [m] (inner radius of the PML).
    pml_thickness : float
        Shell thickness t [m].
    strength : float
        Dimensionless stretch strength ``b`` (> 0).
    profile : {"unbounded", "constant"}

    Returns
    -------
    ngsolve.comp.pml.PML
        Pass to ``mesh.SetPML(..., PML_REGIONS)`` or use :func:`set_pml`.
    """
    from ngsolve import CF, Id, OuterProduct, pml, x, y, z

    if not strength > 0:
        raise ValueError(f"PML strength = {strength!r} is not allowed; allowed: > 0")
    R, t = float(domain_radius), float(pml_thickness)
    if profile == "constant":
        return pml.Radial(origin=(0.0, 0.0, 0.0), rad=R, alpha=1j * float(strength))
    if profile != "unbounded":
        raise ValueError(f"PML profile = {profile!r} is not allowed; allowed: unbounded, constant")
    scale, derivative, direction = radial_stretch((x, y, z), R, t, strength)
    trafo = scale * CF((x, y, z))                           # x~ = scale * x
    # d x~_i / d x_j = scale delta_ij + (dr~/dr - scale) x_i x_j / r^2
    jacobian = scale * Id(3) + (derivative - scale) * OuterProduct(direction, direction)
    return pml.Custom(trafo=trafo, jac=jacobian)


def radial_stretch(position, domain_radius: float, pml_thickness: float,
                   strength: float = PML_STRENGTH):
    """``(s, dr~/dr, e)`` of the unbounded profile (:func:`radial_pml`) at ``position``:
    the stretch ``s = r~/r`` (``x~ = s x``), the radial derivative ``dr~/dr`` and the unit
    radial direction ``e = x/r``, with ``r = |x|``.  ``position``: the coordinates as
    CoefficientFunctions, ``(x, y, z)`` in 3-D (:func:`radial_pml`) or ``(r, z)`` in the
    meridian plane (:func:`copdea_fem.fe.axisymmetric.air.pml_stretch`): the one source of
    the PML profile of both engines."""
    from ngsolve import CF, sqrt

    r = sqrt(sum(component * component for component in position))
    r_stretched, derivative = unbounded_stretch(r, domain_radius, pml_thickness, strength)
    return r_stretched / r, derivative, CF(tuple(position)) / r


def unbounded_stretch(r, domain_radius: float, pml_thickness: float,
                      strength: float = PML_STRENGTH):
    """``(r~, dr~/dr)`` of the unbounded profile (:func:`radial_pml`) at the radius ``r``
    (a CoefficientFunction [m]: the spherical radius, in 3-D or in the meridian plane of
    :mod:`copdea_fem.fe.axisymmetric.air`): ``r~ = r + i b t ln(t / (R + t - r))``."""
    from ngsolve import IfPos, log

    R, t = float(domain_radius), float(pml_thickness)
    # Distance to the outer sphere.  Quadrature points stay inside; the floor
    # only keeps log() finite should a point of a curved element lie on or
    # beyond the sphere (its polynomial approximation).
    floor = 1e-9 * t
    depth_left = IfPos(R + t - r - floor, R + t - r, floor)
    beta = strength * t * log(t / depth_left)              # [m]
    dbeta_dr = strength * t / depth_left                    # [-]
    r_stretched = r + 1j * beta
    return r_stretched, 1 + 1j * dbeta_dr


def set_pml(mesh, domain_radius: float, pml_thickness: float, strength: float = PML_STRENGTH,
            profile: str = "unbounded"):
    """Set the radial PML of :func:`radial_pml` on ``pml_upper|pml_lower`` (replacing any).

    Assemble energy/norm matrices that must stay real *before* calling this;
    ``mesh.UnSetPML(PML_REGIONS)`` removes it.  Returns the PML object.
    """
    stretch = radial_pml(domain_radius, pml_thickness, strength, profile)
    mesh.UnSetPML(PML_REGIONS)
    mesh.SetPML(stretch, PML_REGIONS)
    return stretch


def set_order_in(space, mesh, regions: str, order: int) -> None:
    """Give every element of ``regions`` (cells, faces, edges) polynomial order ``order``.

    Works on 3-D meshes and on the 2-D meridian meshes of :mod:`copdea_fem.fe.axisymmetric`
    (there an element is a FACE node)."""
    from ngsolve import CELL, FACE, VOL, NodeId

    in_regions = mesh.Materials(regions).Mask()
    element_node = CELL if mesh.dim == 3 else FACE
    for element in mesh.Elements(VOL):
        if not in_regions[element.index]:
            continue
        space.SetOrder(NodeId(element_node, element.nr), order)
        if mesh.dim == 3:
            for face in element.faces:
                space.SetOrder(face, order)
        for edge in element.edges:
            space.SetOrder(edge, order)
    space.Update()


def pressure_space(mesh, order: int, screens: str, pml_order: int | None = None,
                   outer_dirichlet: bool = True, also_dirichlet: str = "",
                   vacuum_above: bool = False, outside_jump: bool = False):
    """Complex pressure space ``P x Q`` with a jump across the screens.

    Parameters
    ----------
    mesh : ngsolve.Mesh
        Mesh of :func:`copdea_fem.fe.quadrant.geometry.load_mesh` with air.
    order : int
        Polynomial order of the pressure in the air (``study.mesh.pressure_order``).
    screens : str
        Faces the pressure jumps across (:func:`screen_faces`), names joined
        by ``|``.  On the other plane faces (:func:`open_plane_faces`) ``q`` is
        zero, also on their rim where they touch a screen, so ``[p]`` vanishes
        at a free screen edge.
    pml_order : int, optional
        Order in the PML elements; default ``order + PML_EXTRA_ORDER``.
    outer_dirichlet : bool
        ``p = 0`` on ``outer`` (needed by the unbounded PML profile).
    also_dirichlet : str
        More boundaries with ``p = q = 0`` (the meridian's ``axis`` for an order m >= 1).
    vacuum_above : bool
        Only the air of an enclosure is meshed (``air.outside: false``): ``p = 0`` on the
        screens (the vacuum above them), the cavity's pressure there is ``q``.
    outside_jump : bool
        With an enclosure: the third field ``q_o`` of the lower half, on the plane's screens
        beyond the enclosure's rim (module doc, "Enclosure").

    With an enclosure (a mesh with the volume :data:`CAVITY`) ``q`` lives in the cavity
    instead of the lower half: ``p`` is the outside air's pressure everywhere, ``p + q``
    the cavity's; ``q`` keeps its degrees of freedom on the screens (the walls included
    where outside air lies beyond them, :func:`enclosure_screen_faces`) and is zero on the
    ``vent``, where the cavity opens to the outside air.

    Returns
    -------
    ngsolve.FESpace
        Product space; ``(p, q) = space.TrialFunction()`` etc.  ``p`` [Pa] on
        all air + PML, ``q`` [Pa] on the lower half (the cavity), non-zero only next to the
        screens: ``p_lower = p + q``, ``[p] = -q`` (module doc); ``(p, q, q_o)`` with
        ``outside_jump``.
    """
    from ngsolve import H1, Compress, FESpace

    unknown = set(screens.split("|")) - set(PLANE_FACES) - set(ENCLOSURE_FACES)
    if unknown:
        raise ValueError(f"screens = {screens!r} is not allowed; allowed: names of "
                         f"{', '.join(PLANE_FACES + ENCLOSURE_FACES)} joined by '|'")
    pml_order = order + PML_EXTRA_ORDER if pml_order is None else pml_order
    open_plane = "vent" if has_cavity(mesh) else open_plane_faces(screens)
    outer = "|".join(name for name in (OUTER if outer_dirichlet else "", also_dirichlet) if name)
    continuous = H1(mesh, order=order, complex=True,
                    definedon=mesh.Materials(AIR_AND_PML + "|" + CAVITY),
                    dirichlet="|".join(name for name in (outer, screens if vacuum_above else "")
                                       if name))
    jump = H1(mesh, order=order, complex=True, definedon=mesh.Materials(jump_side(mesh)),
              dirichlet="|".join(name for name in (open_plane, outer) if name))
    spaces = [continuous, jump]
    plane_screens = "|".join(face for face in screens.split("|") if face in PLANE_FACES)
    if outside_jump:
        if not has_cavity(mesh):
            raise ValueError("outside_jump = True is for a mesh with an enclosure (volume "
                             "'cavity'); allowed: False")
        spaces.append(H1(mesh, order=order, complex=True, definedon=mesh.Materials(LOWER),
                         dirichlet="|".join(name for name in (
                             open_plane_faces(plane_screens), "vent", outer) if name)))
    for space in spaces:                 # same basis in all: the bijection needs it
        if pml_order != order:
            set_order_in(space, mesh, PML_REGIONS, pml_order)
    active = jump.GetDofs(mesh.Boundaries(screens)) & jump.FreeDofs()
    if active.NumSet() == 0:
        raise ValueError(f"screens = {screens!r} match no face of the mesh with air; "
                         "allowed: a pattern of membrane, disc, frame, pml_plane")
    components = [continuous, Compress(jump, active_dofs=active)]
    if outside_jump:
        lower_jump = spaces[2]
        components.append(Compress(lower_jump, active_dofs=lower_jump.GetDofs(
            mesh.Boundaries(plane_screens)) & lower_jump.FreeDofs()))
    return FESpace(components)


def region_pressures(pressure) -> list:
    """The pressure of each air volume [Pa] of ``pressure`` (module doc, "Enclosure").

    Parameters
    ----------
    pressure : tuple
        ``(p, q)`` or ``(p, q, q_o)`` of :func:`pressure_space` (trial, test or data).

    Returns
    -------
    list of (str, str, CoefficientFunction)
        ``(air volumes, PML volumes, pressure)``, ``p`` or ``p`` plus a jump field, for the
        volumes the mesh has ('' = none): :func:`pressure_regions`, the outside air's lower
        half on its own with a third field.
    """
    p, q = pressure[0], pressure[1]
    mesh = p.space.mesh
    if len(pressure) == 2:
        parts = [(air, pml, p + q if with_q else p)
                 for air, pml, with_q in pressure_regions(mesh)]
    else:                      # the third field: the outside halves apart
        present = set(mesh.GetMaterials())

        def keep(pattern):
            return "|".join(name for name in pattern.split("|") if name in present)

        parts = [(keep("air_upper"), keep("pml_upper"), p),
                 (keep("air_lower"), keep("pml_lower"), p + pressure[2]), (CAVITY, "", p + q)]
    return [(air, pml, value) for air, pml, value in parts if air or pml]


def outside_pressures(pressure) -> tuple[list, list]:
    """The fields whose sum is the outside air's pressure [Pa] above and below the plane
    (module doc): ``[p]`` and ``[p, q]`` without an enclosure; ``[p]`` and ``[p]`` (``[p,
    q_o]`` with the third field) beside one (``q`` is then the cavity's).  What a sphere
    around the device samples; lists, so that a caller may take the gradient of each."""
    p, q = pressure[0], pressure[1]
    if CAVITY not in p.space.mesh.GetMaterials():
        return [p], [p, q]
    return [p], [p, pressure[2]] if len(pressure) == 3 else [p]


def upper_pressure(pressure):
    """Pressure in the upper half [Pa]: ``p`` (``pressure = (p, q[, q_o])``)."""
    return pressure[0]


def lower_pressure(pressure):
    """Pressure in the lower half (an enclosure's cavity) [Pa]: ``p + q``."""
    return pressure[0] + pressure[1]


def pressure_jump(pressure):
    """``[p] = p+ - p- = -q`` [Pa], to be integrated over the screens (``ds``); over an
    enclosure ``q`` is the cavity's (module doc)."""
    return -pressure[1]


def _over_regions(integrand_of, pressure, pressure_test, deformation):
    """``sum integrand_of(p_region, p'_region) dx`` over the regions of
    :func:`region_pressures`; the mesh deformation (ALE, zero in the PML) only on the air:
    an integral with its own deformation would not see the PML set on the mesh."""
    from ngsolve import dx

    total = None
    for (air, pml, value), (_, _, test) in zip(region_pressures(pressure),
                                               region_pressures(pressure_test)):
        integrand = integrand_of(value, test)
        if deformation is None:
            term = integrand * dx("|".join(name for name in (air, pml) if name))
        else:                  # a PML only around some air (region_pressures): air set
            term = integrand * dx(air, deformation=deformation)
            if pml:
                term = term + integrand * dx(pml)
        total = term if total is None else total + term
    return total


def air_stiffness(pressure, pressure_test, density: float, deformation=None):
    """Stiffness ``k_a = int (1/rho_a) grad p . grad p' dx`` over air + PML (eq. A1).

    Parameters
    ----------
    pressure, pressure_test : tuple or ProxyFunction
        ``(p, q)`` trial and test functions of :func:`pressure_space`, or the
        trial/test functions of a plain H1 space (no screens).
    density : float
        Air density rho_a [kg/m^3].

    Returns
    -------
    ngsolve SumOfIntegrals
        ``K_a p`` is a volume acceleration [m^3/s^2] per unit test pressure.
        With the PML set, NGSolve applies the stretch to ``dx`` and ``grad``.
    """
    from ngsolve import dx, grad

    if not isinstance(pressure, (list, tuple)):      # one continuous field (no screens)
        return (1.0 / density) * grad(pressure) * grad(pressure_test) * dx
    return _over_regions(lambda value, test: (1.0 / density) * grad(value) * grad(test),
                         pressure, pressure_test, deformation)


def air_mass(pressure, pressure_test, density: float, sound_speed: float, deformation=None):
    """Mass ``m_a = int 1/(rho_a c_a^2) p p' dx`` over air + PML (eq. A1).

    Parameters
    ----------
    density : float
        rho_a [kg/m^3].
    sound_speed : float
        c_a [m/s].

    Returns
    -------
    ngsolve SumOfIntegrals
        ``M_a p`` is a volume [m^3] per unit test pressure.
    """
    from ngsolve import dx

    compressibility = 1.0 / (density * sound_speed**2)      # [1/Pa]
    if not isinstance(pressure, (list, tuple)):
        return compressibility * pressure * pressure_test * dx
    return _over_regions(lambda value, test: compressibility * value * test,
                         pressure, pressure_test, deformation)


def screen_coupling(pressure, normal_displacement, screens: str, deformation=None):
    """Coupling ``c(u, p) = int_screens [p] (u . n) ds`` (eqs. A1-A2).

    Parameters
    ----------
    pressure : tuple
        ``(p, q)`` -- trial functions for the membrane row ``c(u', p)``, test
        functions for the air row ``omega^2 c(u, p')``.
    normal_displacement : CoefficientFunction
        ``u . n`` [m] of the screen motion, ``n`` pointing to the + side
        (``u[2]`` or ``w`` for the flat plane); a trial/test function or data.
    screens : str
        Where the screen moves (e.g. ``"membrane"``, ``"membrane|disc"``).

    Returns
    -------
    ngsolve SumOfIntegrals
        Per unit test pressure a volume [m^3] (air row, times omega^2); per unit
        test displacement a force [N] (membrane row).  The virtual work of the
        traction ``-[p] n`` is ``-c(u', p)``, so the membrane row reads
        ``k_s(u,u') + c(u',p) - omega^2 m_s(u,u') = 0``.
    """
    from ngsolve import ds

    return pressure_jump(pressure) * normal_displacement * ds(screens, deformation=deformation)


def coupled_forms(pressure, pressure_test, normal_displacement, normal_displacement_test,
                  membrane_stiffness, membrane_mass, density: float, sound_speed: float,
                  moving_screens: str = "membrane", deformation=None):
    """Integrands of ``A`` and ``B`` in ``A x = omega^2 B x`` (eq. A3), ``x = (u, p)``.

    The one source of the coupled forms: the 3-D engine's assembly
    (:func:`copdea_fem.fe.coupled.assemble_coupled`) calls it, and the sign test
    (``tests/fe/test_acoustics.py``, air loading lowers every frequency) tests it.
    Derivation: module doc, "Weak form" (A1)-(A3).

    Parameters
    ----------
    pressure, pressure_test : tuple
        ``(p, q)`` trial and test functions of :func:`pressure_space`.
    normal_displacement, normal_displacement_test : CoefficientFunction
        ``u . n`` and ``u' . n`` [m] of the membrane trial and test functions.
    membrane_stiffness, membrane_mass : SumOfIntegrals or None
        The caller's membrane forms ``k_s(u, u')`` and ``m_s(u, u')`` (per unit test
        displacement a force [N]); None leaves the term out, for a caller that adds its
        own (the 3-D engine's ``k_s`` is the ``Variation`` of the membrane energy, which
        NGSolve cannot add to a sum of integrals).
    density, sound_speed : float
        rho_a [kg/m^3], c_a [m/s].
    moving_screens : str
        Screens whose motion is the unknown ``u`` (``"membrane"``; add
        ``"|disc"`` when the disc moves with the field ``u``).
    deformation : GridFunction, optional
        The ALE air mesh displacement (:mod:`copdea_fem.fe.ale`): the air and coupling
        terms are integrated on the deformed air (Eulerian), the membrane's as given.

    Returns
    -------
    (a, b) : tuple of SumOfIntegrals
        ``a = k_s(u,u') + c(u',p) + k_a(p,p')``, ``b = m_s(u,u') - c(u,p') + m_a(p,p')``.
    """
    traction, acceleration = coupling_forms(pressure, pressure_test, normal_displacement,
                                            normal_displacement_test, moving_screens,
                                            deformation=deformation)
    a = traction + air_stiffness(pressure, pressure_test, density, deformation=deformation)
    b = acceleration + air_mass(pressure, pressure_test, density, sound_speed,
                                deformation=deformation)
    if membrane_stiffness is not None:
        a = membrane_stiffness + a
    if membrane_mass is not None:
        b = membrane_mass + b
    return a, b


def coupling_forms(pressure, pressure_test, normal_displacement, normal_displacement_test,
                   moving_screens: str = "membrane", deformation=None):
    """The two coupling terms of eq. (A3), with their signs: ``(c(u', p), -c(u, p'))``.

    The first (the air's traction on the screens) goes into ``A``, the second (the
    screens' acceleration driving the air) into ``B``; :func:`coupled_forms` and the
    3-D engine's assembly (:mod:`copdea_fem.fe.coupled`) both take them from here.
    ``deformation``: the ALE air mesh displacement, as :func:`screen_coupling`.
    """
    traction = screen_coupling(pressure, normal_displacement_test, moving_screens,
                               deformation=deformation)
    acceleration = (-1.0) * screen_coupling(pressure_test, normal_displacement, moving_screens,
                                            deformation=deformation)
    return traction, acceleration


def pressure_field(gf_continuous, gf_jump, mesh, gf_outside_jump=None):
    """Pressure CoefficientFunction [Pa] from the GridFunction components.

    Equal to ``p`` in the upper half and ``p + q`` in the lower half; with an enclosure
    ``p + q`` in the cavity, ``p`` outside, ``p + q_o`` in the lower half with a third
    field (``gf_outside_jump``; module doc, "Enclosure").
    """
    field = gf_continuous + mesh.MaterialCF({jump_side(mesh): 1.0}, default=0.0) * gf_jump
    if gf_outside_jump is not None:
        field = field + mesh.MaterialCF({LOWER: 1.0}, default=0.0) * gf_outside_jump
    return field
