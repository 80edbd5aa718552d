"""The imperfections of a device: the keys ``membrane.prestretch_anisotropy``,
``membrane.prestretch_axis``, ``membrane.thickness_variation`` and
``imperfections.point_masses`` read item by item (:func:`read_thickness_variation`,
:func:`read_point_masses`) and checked against the membrane and each other
(:func:`check_imperfections`).

* Anisotropic pre-stretch ``e`` along the axis ``alpha`` [deg, counter-clockwise from x]:
  the film is pre-stretched by ``lambda_p (1 + e)`` along the axis and ``lambda_p (1 - e)``
  across it, then clamped in the round frame of radius ``r_o``; the film's thickness is
  ``h0 / (lambda_p^2 (1 - e^2))`` (incompressible).  A membrane carries no compression, so
  the smaller principal stress of that flat state (:meth:`copdea_fem.fe.materials.Membrane.
  principal_stresses` at ``V = 0`` and stretches ``lambda_p (1 +- e)``) must stay positive:
  that bounds ``e`` for the study's film (the prestress refuses a slack film with its
  ``loss_of_tension`` error); the key's own bound 0.5 (a stretch ratio of 3 between the
  axes) holds whatever the film.
* Thickness variation: ``h0 (1 + sum_j a_j cos k_j (theta - angle_j))`` with orders
  ``k_j >= 1``; ``sum |a_j| < 1`` keeps the film's thickness positive everywhere.
* Point masses ``{mass [kg], r [m], theta [deg]}`` on the membrane (``r_i < r < r_o``) or on
  the rigid disc (``r <= r_i``); a mass on the clamped rim ``r >= r_o`` cannot move and is
  refused.

Angles stay in degrees in the resolved study (the unit of the keys, as
``electrodes.segments``); the FE converts them to radians.  Every default is the perfect
device: a study without these keys resolves, and hashes, as it did before they existed
(:data:`~copdea_fem.study.schema.OPTIONAL_KEYS`, section ``imperfections`` optional).
"""

from __future__ import annotations

import math
from typing import Any

from copdea_fem.study.keys import above, convert_quantity, refusal

#: Most terms of ``membrane.thickness_variation`` / masses of ``imperfections.point_masses``.
MAX_TERMS = 16
#: Highest circumferential order of a thickness term: the 3-D mesh must resolve k periods
#: round the membrane (mesh.membrane_size checks the resolution; 64 is far beyond any
#: measured imperfection).
MAX_THICKNESS_ORDER = 64
THICKNESS_ALLOWED = (f"a list of at most {MAX_TERMS} mappings {{order: integer k in [1, "
                     f"{MAX_THICKNESS_ORDER}], amplitude: a with |a| < 1, angle: degrees "
                     "(default 0)}, with sum |a| < 1: h = h0 (1 + sum a cos k (theta - angle))")
MASSES_ALLOWED = (f"a list of at most {MAX_TERMS} mappings {{mass: kg > 0, r: metres in [0, "
                  "geometry.outer_radius), theta: degrees (default 0)}")

#: The keys whose non-default values make a device imperfect (for messages).
IMPERFECTION_KEYS = ("membrane.prestretch_anisotropy", "membrane.thickness_variation",
                     "imperfections.point_masses")


def read_thickness_variation(key: str, value: Any) -> list:
    """``membrane.thickness_variation`` (mappings or
    :class:`~copdea_fem.study.sections.ThicknessTerm`) -> ``[{"order": k, "amplitude": a,
    "angle": [deg]}, ...]``, each term bounded alone (their sum: :func:`check_imperfections`)."""
    if value is None:
        value = []
    if not isinstance(value, (list, tuple)) or len(value) > MAX_TERMS:
        raise refusal(key, value, THICKNESS_ALLOWED)
    terms = []
    for index, item in enumerate(value):
        where = f"{key}[{index}]"
        if hasattr(item, "plain"):
            item = item.plain()
        if not isinstance(item, dict) or not {"order", "amplitude"} <= set(item) \
                or not set(item) <= {"order", "amplitude", "angle"}:
            raise refusal(where, item, THICKNESS_ALLOWED, "each term needs the keys order and "
                          "amplitude, and may have angle")
        order = convert_quantity(f"{where}.order", item["order"], "", 1, MAX_THICKNESS_ORDER)
        if not float(order).is_integer():
            raise refusal(f"{where}.order", item["order"],
                          f"an integer in [1, {MAX_THICKNESS_ORDER}]")
        amplitude = convert_quantity(f"{where}.amplitude", item["amplitude"], "", -1, 1)
        if not above(1.0, abs(amplitude)):
            raise refusal(f"{where}.amplitude", item["amplitude"], "|a| < 1",
                          "the film would vanish where cos k (theta - angle) = -sign(a)")
        angle = convert_quantity(f"{where}.angle", item.get("angle", 0.0), "deg", -360, 360)
        terms.append({"order": int(order), "amplitude": amplitude, "angle": angle})
    return terms


def read_point_masses(key: str, value: Any) -> list:
    """``imperfections.point_masses`` (mappings or
    :class:`~copdea_fem.study.sections.PointMass`) -> ``[{"mass" [kg], "r" [m], "theta"
    [deg]}, ...]``, each bounded alone (against the geometry: :func:`check_imperfections`)."""
    if value is None:
        value = []
    if not isinstance(value, (list, tuple)) or len(value) > MAX_TERMS:
        raise refusal(key, value, MASSES_ALLOWED)
    masses = []
    for index, item in enumerate(value):
        where = f"{key}[{index}]"
        if hasattr(item, "plain"):
            item = item.plain()
        if not isinstance(item, dict) or not {"mass", "r"} <= set(item) \
                or not set(item) <= {"mass", "r", "theta"}:
            raise refusal(where, item, MASSES_ALLOWED, "each mass needs the keys mass and r, "
                          "and may have theta")
        mass = convert_quantity(f"{where}.mass", item["mass"], "kg", 0, 100)
        if not above(mass, 0.0):
            raise refusal(f"{where}.mass", item["mass"], "> 0 kg")
        radius = convert_quantity(f"{where}.r", item["r"], "m", 0, 1)
        theta = convert_quantity(f"{where}.theta", item.get("theta", 0.0), "deg", -360, 360)
        masses.append({"mass": mass, "r": radius, "theta": theta})
    return masses


def imperfection_keys_given(membrane, imperfections) -> str:
    """The keys of :data:`IMPERFECTION_KEYS` a study's sections (typed, or the plain
    mappings of the checks) set, comma-separated ("" for a perfect device)."""
    get = (lambda section, key: section[key]) if isinstance(membrane, dict) else getattr
    given = (get(membrane, "prestretch_anisotropy"), get(membrane, "thickness_variation"),
             get(imperfections, "point_masses"))
    return ", ".join(key for key, value in zip(IMPERFECTION_KEYS, given) if value)


def imperfections_given(study) -> str:
    """``"key = value, ..."`` of the imperfection keys a :class:`~copdea_fem.study.Study`
    sets ("" for a perfect device): what a refusal of an imperfect study names."""
    keys = imperfection_keys_given(study.membrane, study.imperfections)
    return ", ".join(f"{key} = {study.get(key)!r}" for key in keys.split(", ")) if keys else ""


def is_imperfect(membrane, imperfections) -> bool:
    """Whether a study's sections (typed or plain mappings) hold any imperfection."""
    return bool(imperfection_keys_given(membrane, imperfections))


#: Largest imperfection the axisymmetric engine's first-order perturbation path takes
#: (:mod:`copdea_fem.fe.axisymmetric.perturbation`): ``e + sum |a|`` [-].  The terms it
#: leaves out at every order are O(s^2) relative (the e^2 of the pre-stretch's B_p and
#: det F_p, the second-order correction of the state): s <= 0.03 keeps them near 1e-3,
#: the path's own tolerance on the second-order shifts it checks after the solve.
PERTURBATION_MAX_SIZE = 0.03
#: Largest total point mass the perturbation path takes, as a share of the film's mass
#: ``rho0 h0 / lambda_p^2 pi (r_o^2 - r_i^2)`` [-].  A mass dm enters the mass matrix exactly
#: (``dm phi_i(x0) . phi_j(x0)``); what the path leaves out is perturbation theory's next
#: order, O((P mu)^2) relative with ``mu = dm / M_film`` and ``P = M_film |phi(x0)|^2 /
#: M_modal`` the mode's concentration at the point (its first-order shift is ``P mu / 2``).
#: On the flat membrane P peaks at the centre for the (0,n) modes: ``1 / J_1(j_0n)^2`` =
#: 3.7, 8.6, 13.5 for n = 1, 2, 3, and ``2 max J_m^2 / J_{m+1}(j_mn)^2`` = 4.2 for (1,1): so
#: P <= 10 for the modes a band of a few nodal circles holds, and ``P mu <= 0.03`` (as
#: ``s <= 0.03`` for e and a, the neglected terms near 1e-3) gives ``mu <= 3e-3``.  A mass
#: on the disc is counted against the film alone (conservative: the disc's mass adds to
#: the modal mass).  The path checks the actual neglected term after the solve.
PERTURBATION_MAX_MASS_RATIO = 3e-3


def film_mass(membrane, geometry) -> float:
    """The film's mass [kg]: ``rho0 h0 / lambda_p^2`` (the flat pre-stretched areal density)
    times the annulus ``pi (r_o^2 - r_i^2)``; sections typed or the checks' plain mappings."""
    get = (lambda section, key: section[key]) if isinstance(membrane, dict) else getattr
    density = get(membrane, "density") * get(membrane, "thickness") / \
        get(membrane, "prestretch") ** 2
    r_o, r_i = get(geometry, "outer_radius"), get(geometry, "inner_radius")
    return density * math.pi * (r_o**2 - r_i**2)


def perturbation_refusal(membrane, imperfections, geometry) -> tuple | None:
    """Why the axisymmetric engine's perturbation path cannot take a study's imperfection:
    ``(key, value, allowed)``, or None where it can (a study, dry or in air, with an anisotropy and
    thickness terms of total size ``e + sum |a| <= PERTURBATION_MAX_SIZE`` and point masses
    of total ``sum dm <= PERTURBATION_MAX_MASS_RATIO`` times the film's mass, :func:`film_mass`).
    ``membrane``, ``imperfections``, ``geometry``: typed sections or the checks' plain
    mappings."""
    get = (lambda section, key: section[key]) if isinstance(membrane, dict) else getattr
    masses = [m["mass"] if isinstance(m, dict) else m.mass
              for m in get(imperfections, "point_masses")]
    limit = PERTURBATION_MAX_MASS_RATIO * film_mass(membrane, geometry)
    if sum(masses) > limit:
        return ("imperfections.point_masses", [float(f"{m:.6g}") for m in masses],
                (f"masses [kg] summing to <= {PERTURBATION_MAX_MASS_RATIO:g} of the film's "
                 f"mass = {limit:.4g} kg on the axisymmetric engine (its first-order "
                 "perturbation's range; the 3-D engine takes more)"))
    anisotropy = get(membrane, "prestretch_anisotropy")
    terms = get(membrane, "thickness_variation")
    amplitudes = [t["amplitude"] if isinstance(t, dict) else t.amplitude for t in terms]
    size = anisotropy + sum(abs(a) for a in amplitudes)
    if size > PERTURBATION_MAX_SIZE:
        key = ("membrane.prestretch_anisotropy" if not amplitudes else
               "membrane.thickness_variation" if not anisotropy else
               "membrane.prestretch_anisotropy + membrane.thickness_variation")
        return (key, round(size, 12), (f"e + sum |a| <= {PERTURBATION_MAX_SIZE:g} on the "
                                        "axisymmetric engine (its first-order perturbation's "
                                        "range; the 3-D engine takes more)"))
    return None


def check_imperfections(v: dict[str, dict[str, Any]]) -> None:
    """The imperfections against the film and the geometry (module notes); a
    :class:`~copdea_fem.study.keys.StudyError` names the key.  The tension across the
    anisotropy's axis needs the film's constitutive law: the prestress checks it (its
    ``loss_of_tension`` error, :mod:`copdea_fem.fe.prestress`)."""
    m, g = v["membrane"], v["geometry"]
    terms = m["thickness_variation"]
    if terms and not above(1.0, sum(abs(t["amplitude"]) for t in terms)):
        raise refusal("membrane.thickness_variation",
                      [t["amplitude"] for t in terms], "amplitudes with sum |a| < 1",
                      "the film's thickness would reach zero")
    r_o, r_i = g["outer_radius"], g["inner_radius"]
    for index, point in enumerate(v["imperfections"]["point_masses"]):
        if not above(r_o, point["r"]):
            where = "the disc or the membrane" if r_i > 0 else "the membrane"
            raise refusal(f"imperfections.point_masses[{index}].r", point["r"],
                          f"[0, {r_o:g}) m = on {where} (below geometry.outer_radius)",
                          "a mass on the clamped rim cannot move")


__all__ = [
    "IMPERFECTION_KEYS",
    "MASSES_ALLOWED",
    "MAX_TERMS",
    "PERTURBATION_MAX_MASS_RATIO",
    "PERTURBATION_MAX_SIZE",
    "THICKNESS_ALLOWED",
    "check_imperfections",
    "film_mass",
    "imperfection_keys_given",
    "imperfections_given",
    "is_imperfect",
    "perturbation_refusal",
    "read_point_masses",
    "read_thickness_variation",
]
