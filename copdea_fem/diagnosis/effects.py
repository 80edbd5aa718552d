"""Catalogue of the physical effects the model can switch on or off.

Every effect is a transformation of the study: :meth:`Effect.on` returns the
``{"section.key": value}`` overrides that switch it on with given parameter
values, :meth:`Effect.off` those that switch it off, and :meth:`Effect.is_on`
reads whether a study already has it.  The reduced model
(:func:`copdea_fem.reduced.build_reduced`) honours every key involved, so a
diagnosed model is an ordinary study file.

Parameters (0 to 2 per effect; 3 for an imperfection, never tabulated by the search)
carry SI units (angles in degrees, as the study keys), fit bounds and a physical
default; ``log = True`` means they are fitted in log space (scale factors,
masses, times).  ``kind`` is ``"physics"`` (a mechanism the model lacks) or
``"parameter"`` (the model has the mechanism but a parameter of the study is
off, e.g. ``uniform_stiffness``).  ``engine`` is ``"reduced"`` when the
ring surrogate can move it, ``"coupled_fe"`` when only the fully-coupled
FE can (tested only with the FE as the model of record and air in the model)
and ``"fe"`` when the FE is its model of record in vacuo or with air (tested only
with ``model: fe``: ``viscoelastic_membrane``).

An :class:`Effect` is the single description of its effect: besides what it does to
a study, its fields say how the FE represents it (``fe_role``), whether the FE
evaluates it alone (``direct``), whether a synthetic vibrometer export can hide it
(``visible_in_scan``), whether it is a mounting and what it replaces, which effects
it excludes, when it applies to the data (:meth:`Effect.applies_to`) and which
study keys a condition may not set because it switches them.  The rest of the
diagnosis reads these fields and never names an effect; the catalogue-level sets
below (:data:`MOUNTINGS`, :data:`DEFAULT_CANDIDATES`, ...) are derived from them.
Adding an effect is adding one :class:`Effect` to the catalogue (the record and its
parts: :mod:`copdea_fem.diagnosis.effect_record`).

Identifiers are a contract (``diagnosis.json``): ``air_loading,
electrostatic_softening, spring_mass, disc_pumping, modal_damping,
frame_reflection, viscoelastic_stiffening, uniform_stiffness``, ``baffle``,
``open_air``, ``viscoelastic_membrane``, ``enclosure`` and the imperfections
``anisotropic_prestretch``, ``thickness_variation``, ``point_mass`` (named from split
pairs after the search, :mod:`copdea_fem.diagnosis.imperfections`; never candidates of
the search: :data:`IMPERFECTIONS`).

:data:`DEFAULT_CANDIDATES` (what ``measured.yaml`` may add when it lists no
``candidates``) is every effect but :data:`OPT_IN` (``enclosure``: named in
``candidates`` to be tested; docs/diagnosis-mounting.md says why) and the
:data:`IMPERFECTIONS` (tested after the search, from the split pairs: all of them when
``candidates`` is absent, those it names otherwise).
"""

from __future__ import annotations

import math

from copdea_fem.diagnosis.effect_record import (  # noqa: F401  (the catalogue's names)
    BIASED,
    FE_ROLES_ALLOWED,
    HAS_DISC,
    MOUNTING_KINDS,
    RAISED,
    Effect,
    Exclusion,
    Parameter,
    Requirement,
    SplitSignature,
    SplitTrial,
)
from copdea_fem.measured import EffectRules
from copdea_fem.study import ENCLOSURE_AIR_SHARE, PronyTerm, StudyError

# Modal damping b/m of Sect. 5.3 [1/s]: the physical default of effect modal_damping.
PAPER_DAMPING = {"reduced.damping_p1": 45.0, "reduced.damping_01": 245.0,
                 "reduced.damping_02": 57.0, "reduced.damping_higher": 57.0}


def _air_on(study, values):
    return {"effects.air_added_mass": "incompressible", "effects.air_mass_scale": values[0],
            "air.enabled": True}


def _air_off(study):
    return {"effects.air_added_mass": "none", "effects.air_mass_scale": 1.0,
            "reduced.modes_json": None, "reduced.coupled_freq_01": None,
            "reduced.coupled_freq_02": None, "air.enabled": False}


def _air_detect(study):
    r = study.reduced
    return (study.effects.air_added_mass != "none" or bool(r.modes_json)
            or r.coupled_freq_01 is not None or r.coupled_freq_02 is not None
            or study.air.enabled)


CATALOGUE: dict[str, Effect] = {}


def _register(effect: Effect) -> None:
    CATALOGUE[effect.id] = effect


_register(Effect(
    id="air_loading", title="acoustic loading (air added mass)",
    description="The air on both faces adds inertia to the membrane (Sect. 3.1.2, eq. 8): the "
                "fully-coupled FE lowers the dry frequencies by up to 30 % (Fig. 10).  Reduced "
                "engine: coupled frequencies from the condition's modes.json when given, else "
                "the incompressible-air added mass of a baffled membrane on both faces "
                "(copdea_fem.reduced.airmass), times a scale factor.",
    kind="physics", engine="reduced",
    parameters=(Parameter("scale", "effects.air_mass_scale", None, 1.0, 0.25, 4.0, True,
                          "factor on the added masses (1 = the baffled incompressible "
                          "estimate or the FE's coupled frequencies)", surrogate_only=True),),
    signature="every axisymmetric membrane mode measured below the dry model, (0,1) most "
              "(added mass 45-80 % of its modal mass in Sect. 5.1) and (0,2) less (25-30 %), "
              "the pumping modes hardly at all; the added mass grows with z",
    on_overrides=_air_on, off_overrides=_air_off, detect=_air_detect,
    fe_role="switch", direct=True, visible_in_scan=True, adds_air=True,
    switched_keys=("reduced.modes_json", "reduced.coupled_freq_0", "air.enabled")))

_register(Effect(
    id="electrostatic_softening", title="electrostatic (Maxwell) softening",
    description="The co-energy of eq. (7) lowers the membrane stress and the stiffness K_s "
                "(eq. 14) in proportion to V_b^2: structural frequencies fall as the bias "
                "rises (Figs 8a, 11a).  Parameter: a factor on the electrostatic term (an "
                "effective permittivity relative to membrane.relative_permittivity).",
    kind="physics", engine="reduced",
    parameters=(Parameter("scale", "effects.maxwell_scale", None, 1.0, 0.25, 2.5, True,
                          "factor on the electrostatic term (1 = eq. 7 with the nominal "
                          "permittivity)"),),
    signature="model frequencies too high by an error that grows with V_b^2, the same sign "
              "for every membrane mode; P1 (k_DE) shifts a little too",
    on_overrides=lambda s, v: {"effects.maxwell_scale": v[0]},
    off_overrides=lambda s: {"effects.maxwell_scale": 0.0},
    detect=lambda s: s.effects.maxwell_scale > 0,
    fe_role="anchored", direct=True, changes_prestress=True, applies_when=(BIASED,)))

_register(Effect(
    id="spring_mass", title="biasing-spring distributed mass (pumping modes P2, P3, ...)",
    description="The biasing spring's own mass M_s carries longitudinal waves (Annex I, eqs "
                "21-23): P1 drops below sqrt((k_DE + k_d)/M_d) and further pistonic peaks P2, "
                "P3, ... appear at low frequency.",
    kind="physics", engine="reduced",
    parameters=(Parameter("mass", "spring.mass", "kg", 1.8e-3, 0.2e-3, 10e-3, True,
                          "spring mass M_s (Table 1: 1.8 g)"),),
    signature="extra low-frequency pistonic peaks (P2, P3: the disc and membrane move together) "
              "that the model lacks, and P1 below the massless-spring value",
    on_overrides=lambda s, v: {"spring.mass": v[0], "reduced.pumping_added_mass": "spring"},
    off_overrides=lambda s: {"spring.mass": 0.0},
    detect=lambda s: s.spring.mass > 0,
    requires=("disc_pumping",), applies_when=(RAISED,),
    switched_keys=("spring.mass", "reduced.pumping_added_mass")))

_register(Effect(
    id="disc_pumping", title="disc pumping mode P1 (disc on the spring)",
    description="The disc rides on the biasing spring instead of being held: the pumping mode "
                "P1 appears (Sect. 4.3, Fig. 7a), where membrane and disc move pistonically.  "
                "The voltage excites it only when z > 0 (at z = 0, dC/dz = 0).",
    kind="physics", engine="reduced", parameters=(),
    signature="a low-frequency pistonic peak (disc moving) below the membrane modes, absent "
              "from a model with the disc held",
    on_overrides=lambda s, v: {"disc.motion": "spring"},
    off_overrides=lambda s: {"disc.motion": "held"},
    detect=lambda s: s.disc.motion == "spring",
    fe_role="anchored", direct=True, visible_in_scan=True, applies_when=(HAS_DISC, RAISED),
    switched_keys=("disc.motion",)))

_register(Effect(
    id="modal_damping", title="modal damping",
    description="Diagonal modal damping b/m of eq. (19), calibrated in Sect. 5.3 (45, 245, 57 "
                "1/s for P1, (0,1), (0,2)); parameter: a common factor on those values.",
    kind="physics", engine="reduced",
    parameters=(Parameter("scale", "reduced.damping_*", None, 1.0, 0.05, 20.0, True,
                          "factor on the b/m of Sect. 5.3"),),
    signature="finite peak widths (quality factors) and peak heights; an undamped model has "
              "infinitely sharp peaks while the frequencies barely move",
    on_overrides=lambda s, v: {key: v[0] * value for key, value in PAPER_DAMPING.items()},
    off_overrides=lambda s: {key: 0.0 for key in PAPER_DAMPING},
    detect=lambda s: any(s.get(key) > 0 for key in PAPER_DAMPING),
    needs="quality_factors", switched_keys=("reduced.damping_",)))

# G1's frame over its membrane diameter (Sect. 5.1: an 80 mm square around r_o = 35.5 mm):
# the size of a frame the base study does not state validly for its membrane.
FRAME_OVER_DIAMETER = 0.080 / 0.071
# A mounting's overrides state the whole mounting (the frame and the closed back), so that
# one replaces another: the open mountings clear the enclosure, the enclosure the frame.
NO_ENCLOSURE = {"geometry.enclosure": "none"}


def frame_overrides(study, shape=None) -> dict:
    """Overrides that put the membrane in a reflecting frame.

    Shape: the base study's ``geometry.frame`` when it is square or circle, else square
    (Sect. 5.1).  Size: the study's ``geometry.frame_side`` / ``frame_radius`` (stated)
    when it fits the membrane and the air sphere, else G1's proportion
    (:data:`FRAME_OVER_DIAMETER` x 2 r_o) -- so any membrane size has a frame; the air
    sphere grows to keep a square frame's corners inside it (R >= 1.1 x side / sqrt 2).
    """
    g, air = study.geometry, study.air
    shape = shape or (g.frame if g.frame in ("square", "circle") else "square")
    r_o, radius = g.outer_radius, air.domain_radius
    out = {"geometry.frame": shape, **NO_ENCLOSURE}
    if shape == "square":
        side = g.frame_side
        if side <= 2 * r_o:
            side = out["geometry.frame_side"] = FRAME_OVER_DIAMETER * 2 * r_o
            out["geometry.frame_radius"] = 0.5 * side       # its derived default, kept in step
        if side / 2 ** 0.5 >= radius:
            out["air.domain_radius"] = 1.1 * side / 2 ** 0.5
    else:
        frame_radius = g.frame_radius
        if not r_o < frame_radius < radius:
            frame_radius = out["geometry.frame_radius"] = FRAME_OVER_DIAMETER * r_o
        if frame_radius >= radius:
            out["air.domain_radius"] = 1.1 * frame_radius
    return out


_register(Effect(
    id="frame_reflection", title="reflecting frame",
    description="A rigid frame in the membrane plane around it reflects the membrane's sound "
                "(Sect. 5.1: the square 80 mm frame); the paper blames its remaining <= 8 % "
                "error on reflecting parts near the device (Sect. 5.2).  Only the coupled "
                "air/PML FE can represent it: the base study's frame shape and size when it "
                "states a square or circle frame that fits the membrane, else a square of G1's "
                "proportion (side 1.13 x the membrane diameter; 80 mm for G1); the circle on "
                "the axisymmetric engine, the square on the 3-D quadrant.  The ring model has "
                "no frame.",
    kind="physics", engine="coupled_fe", parameters=(),
    signature="mode-dependent shifts of a few per cent, largest on (0,1) (Sect. 5.2): a "
              "weaker baffle -- the (0,n) modes lowered most, the (m,1) less, falling with m "
              "(0.65 m drum head in a square of side 0.73 m, coupled FE: (0,1) -3.7 %, (1,1) "
              "-2.2 %, (2,1) -1.4 %, (0,2) -2.1 %); split (m,n) pairs (square frame only: "
              "a/b of m = 2 shifted differently)",
    on_overrides=lambda s, v: frame_overrides(s),
    off_overrides=lambda s: {"geometry.frame": "none"},
    detect=lambda s: (s.geometry.frame in ("square", "circle")
                      and s.geometry.enclosure == "none"),
    fe_role="switch", direct=True, visible_in_scan=True, mounting="built",
    switched_keys=("geometry.frame",),
    not_tested_note="frame_reflection needs the fully-coupled air/PML FE (model: fe) with air "
                    "in the model; it was skipped, not rejected."))

_register(Effect(
    id="baffle", title="membrane in an infinite baffle (mounting)",
    description="The membrane's rim sits in an infinite rigid plane (a drum head in a wall, a "
                "loudspeaker in a box front): the air cannot flow round the rim from "
                "one face to the other.  Evaluated with the coupled air/PML FE on the "
                "axisymmetric engine (geometry.frame: baffle); the ring model has no baffle.",
    kind="physics", engine="coupled_fe", parameters=(),
    signature="every membrane mode lower than open in air, (0,1) most (a monopole: the baffle "
              "blocks the short circuit round the rim), (0,2) and the (m,1) modes less, "
              "falling with m (0.65 m drum head, coupled FE: (0,1) -12 %, (1,1) -4.4 %, (2,1) "
              "-2.2 %, (3,1) -1.3 %, (0,2) -3.1 %; G1 at z = 11 mm, 2 kV: (0,1) -9 %, (1,1) -3 %); "
              "no split pairs (axisymmetric)",
    on_overrides=lambda s, v: {"geometry.frame": "baffle", **NO_ENCLOSURE},
    off_overrides=lambda s: {"geometry.frame": "none"},
    detect=lambda s: (s.geometry.frame == "baffle"
                      and s.geometry.enclosure == "none"),
    fe_role="switch", direct=True, visible_in_scan=True, mounting="built"))

_register(Effect(
    id="open_air", title="membrane open in air (the base's mounting removed)",
    description="The reverse of baffle, frame_reflection and enclosure: the membrane hangs "
                "open in air, nothing in its plane around it nor behind it, so the air flows "
                "round the rim from one face to the other.  A candidate only for a base that "
                "states a mounting (geometry.frame: baffle, square or circle, or an enclosure, "
                "with air): it replaces that mounting by geometry.frame: none, "
                "geometry.enclosure: none.  Evaluated with the coupled air/PML "
                "FE on the axisymmetric engine; the ring model has no mounting.",
    kind="physics", engine="coupled_fe", parameters=(),
    signature="every membrane mode higher than the baffled model predicts, (0,1) most (the "
              "air short-circuits round the rim: a monopole loses much of its added mass), "
              "(0,2) and the (m,1) less, the less the higher m (coupled FE, open over "
              "baffled: 0.65 m drum head at pre-stretch 1.05, (0,1) +14.1 %, (1,1) +4.6 %, "
              "(2,1) +2.2 %, (3,1) +1.4 %, (0,2) +3.2 %; G1 at z = 11 mm, 2 kV, (0,1) "
              "+10.2 %, (1,1) +2.8 %, (2,1) +1.2 %, (0,2) +0.4 %); against a frame, the "
              "same pattern by a few per cent; the split (m,n) pairs of a square frame merge",
    on_overrides=lambda s, v: {"geometry.frame": "none", **NO_ENCLOSURE},
    off_overrides=lambda s: {"geometry.frame": "baffle"},
    detect=lambda s: (s.geometry.frame == "none"
                      and s.geometry.enclosure == "none"),
    fe_role="switch", direct=True, visible_in_scan=True, mounting="open"))

# Fit bounds of enclosure's depth over r_o: from a shallow gap (0.05 r_o, above the
# schema's 0.02 r_o meshing floor) to a deep can (2 r_o: its far corner, sqrt(5) r_o,
# inside 0.8 of the default air sphere of 3.5 r_o).
ENCLOSURE_DEPTH_RATIO = (0.05, 2.0)


def enclosure_overrides(study, values) -> dict:
    """Overrides of :data:`enclosure <CATALOGUE>`: a sealed rigid cylinder of the outer
    radius r_o and depth ``values[0]`` x r_o under the membrane (volume
    V = pi r_o^3 values[0]), standing in free air (``geometry.frame: none``: it replaces
    the base's frame or baffle), the outside air kept (``air.outside: true``); the air
    sphere grows to keep the cylinder's far corner within
    :data:`~copdea_fem.study.ENCLOSURE_AIR_SHARE` of its radius (1.1 x the least)."""
    r_o = study.geometry.outer_radius
    depth = float(values[0]) * r_o
    out = {"geometry.frame": "none", "geometry.enclosure": "cylinder",
           "geometry.enclosure_depth": depth, "geometry.enclosure_radius": r_o,
           "geometry.enclosure_vent_radius": 0.0, "air.outside": True}
    farthest = math.hypot(r_o, depth)
    if farthest >= ENCLOSURE_AIR_SHARE * study.air.domain_radius:
        out["air.domain_radius"] = 1.1 * farthest / ENCLOSURE_AIR_SHARE
    return out


_register(Effect(
    id="enclosure", title="sealed enclosure under the membrane (mounting: a closed back)",
    description="A rigid sealed cylinder of the membrane's outer radius under it (a closed "
                "box, a drum's kettle, a pump's chamber; docs/enclosures.md): the trapped "
                "air is a spring on every mode that changes its volume, it has acoustic modes "
                "of its own, and it blocks the back radiation.  The cylinder stands in free "
                "air (geometry.frame: none, geometry.enclosure: cylinder, sealed), replacing "
                "the base's frame or baffle; its depth L is fitted (as L / r_o: the volume "
                "V = pi r_o^2 L).  For a flat membrane of tension T over a shallow cavity "
                "the air spring's strength is B = rho c^2 pi r_o^4 / (T V).  Evaluated with "
                "the coupled air/PML FE (the air inside meshed like the outside), directly "
                "or as the anchor of the ring model, one FE solve per depth; the ring model "
                "has no enclosure.  Not a default candidate: name it in measured.yaml's "
                "candidates.",
    kind="physics", engine="coupled_fe",
    parameters=(Parameter("depth_ratio", "geometry.enclosure_depth", None, 1.0,
                          *ENCLOSURE_DEPTH_RATIO, True,
                          "depth L of the sealed cylinder over the outer radius r_o "
                          "(1: L = r_o, the study's default depth)"),),
    signature="the (0,n) modes, which change the trapped volume, measured far above the "
              "open model, (0,1) most (the air spring: for a flat membrane x^2 J0(x) + "
              "B J2(x) = 0, x = k r_o, k1 r_o from 2.405 open to 3.020 at B = 5), the (0,2) "
              "less (its volume change nearly cancels); the m >= 1 modes change no volume: "
              "not stiffened, only lowered a little by the confined air's added mass, the "
              "less the higher m (coupled FE, 0.65 m drum head at pre-stretch 1.05 over a "
              "cylinder 0.6 r_o deep, against open in air: (0,1) +118 %, (0,2) +10.5 %, "
              "(1,1) -10.3 %, (2,1) -4.0 %, (3,1) -2.3 %, (4,1) -1.5 %; G1 at z = 16 mm, "
              "2 kV in a baffle over a 20 mm deep cylinder, B ~ 300: (0,1) 378 -> 1022 Hz, "
              "past the (0,2), (1,1) -2 %); the stiffening grows as the cavity gets "
              "shallower (B ~ 1/V) and saturates (the (0,1) tends to the first zero of "
              "J2, k r_o = 5.14); the cavity's own acoustic modes (cavity(m,n,p), kHz for a "
              "few cm) appear as air modes, not membrane resonances; no split pairs",
    on_overrides=enclosure_overrides,
    off_overrides=lambda s: dict(NO_ENCLOSURE),
    detect=lambda s: s.geometry.enclosure != "none",
    # opt-in: a sealed back is built, not hidden (the base states it, and then the other
    # mountings are tested in its place), and its fitted depth costs FE solves on a grid
    # per condition
    fe_role="switch", direct=True, mounting="built", opt_in=True))

_register(Effect(
    id="viscoelastic_stiffening", title="visco-elastic stiffening",
    description="A standard linear solid (quasi-linear visco-elasticity, Sect. 3.1.1 eq. 5's "
                "S_v): the membrane's elastic stiffness grows with frequency by the storage "
                "factor 1 + Delta (w tau)^2 / (1 + (w tau)^2).  Defaults: Delta = 0.3, tau = "
                "0.2 ms (a silicone film's storage modulus rising by tens of per cent over the "
                "0-1 kHz band).",
    kind="physics", engine="reduced",
    parameters=(Parameter("strength", "effects.viscoelastic_strength", None, 0.3, 0.02, 3.0, True,
                          "Delta: glassy over relaxed modulus minus 1"),
                Parameter("time", "effects.viscoelastic_time", "s", 2e-4, 1e-5, 1e-2, True,
                          "relaxation time tau")),
    signature="a model error that grows with frequency: (0,2) under-predicted more than (0,1), "
              "the pumping modes (tens of Hz) untouched, the same at every z and V_b",
    on_overrides=lambda s, v: {"effects.viscoelastic_strength": v[0],
                               "effects.viscoelastic_time": v[1]},
    off_overrides=lambda s: {"effects.viscoelastic_strength": 0.0},
    detect=lambda s: s.effects.viscoelastic_strength > 0))

def prony_overrides(study, values) -> dict:
    """Overrides of :data:`viscoelastic_membrane <CATALOGUE>`: one Prony term
    ``{modulus_ratio: g, relaxation_time: tau [s]}`` in place of the study's series, the
    modal b/m of Sect. 5.3 off (the material's loss replaces the hand calibration), and
    ``eigen.f_min`` raised to half the lowest relaxation frequency
    ``1 / (2 pi tau (1 + g))`` where that spectrum would reach the FE's band (the study's
    check, :mod:`copdea_fem.study`: only for tau (1 + g) >~ 1.3 ms with the default band)."""
    ratio, time = float(values[0]), float(values[1])
    out = {"membrane.prony": [{"modulus_ratio": ratio, "relaxation_time": time}],
           **{key: 0.0 for key in PAPER_DAMPING}}
    floor = prony_band_floor([PronyTerm(ratio, time)], study.eigen)
    if floor is not None:
        out["eigen.f_min"] = floor
    return out


def prony_band_floor(terms, eigen, f_max: float | None = None) -> float | None:
    """The ``eigen.f_min`` [Hz] that keeps the relaxation spectrum of the Prony ``terms``
    (:class:`PronyTerm`; Re f = 0, |Im f| >= 1 / (2 pi tau_max (1 + sum g))) out of the FE's
    band, where the study's check (:func:`copdea_fem.study.parse_study`) would refuse
    ``eigen`` (the study's section ``study.eigen``; ``f_max`` [Hz] in place of its own, the
    diagnosis's FE band); None: no change."""
    if not terms:
        return None
    lowest = 1.0 / (2 * math.pi * max(t.relaxation_time for t in terms)
                    * (1 + sum(t.modulus_ratio for t in terms)))
    top = eigen.f_max if f_max is None else f_max
    if eigen.f_min < 0.5 * lowest and lowest <= 2 * eigen.max_damping_ratio * top:
        return 0.5 * lowest
    return None


_register(Effect(
    id="viscoelastic_membrane", title="viscoelastic membrane (Prony term, evaluated by the FE)",
    description="The film is a generalised Maxwell material (docs/damping.md): one "
                "Prony term membrane.prony = [{modulus_ratio: g, relaxation_time: tau}] on the "
                "material tangent, K_mat (1 + g (-i w tau) / (1 - i w tau)), the hyperelastic "
                "law of eq. (20) its relaxed modulus.  It stiffens the membrane by the storage "
                "factor 1 + g (w tau)^2 / (1 + (w tau)^2) and damps it by the loss factor "
                "g w tau / (1 + (w tau)^2), both on the material share of each mode's strain "
                "energy; the FE's damped eigen step gives the complex frequencies, Q = "
                "1 / (2 zeta).  Replaces the paper's modal b/m (modal_damping's keys set to "
                "0) and is never named beside modal_damping or viscoelastic_stiffening.  An "
                "out-of-plane mode of the flat membrane (z = 0) has no material strain at "
                "first order, so no material damping nor stiffening (docs/damping.md): data "
                "at z > 0 carry the evidence.  Needs model: fe and measured quality factors.",
    kind="physics", engine="fe",
    parameters=(Parameter("ratio", "membrane.prony[0].modulus_ratio", None, 0.5, 0.05, 10.0,
                          True, "g: the branch's modulus over the relaxed (long-term) one"),
                Parameter("time", "membrane.prony[0].relaxation_time", "s", 2e-4, 1e-5, 2e-3,
                          True, "relaxation time tau (the loss peaks at w tau = 1)")),
    signature="finite quality factors that follow a Maxwell term: each mode's damping ratio "
              "zeta = g s w tau / (2 (1 + (w tau)^2)) (s its material share of strain energy) "
              "peaks near w tau = 1, and frequencies raised a little, more at higher w tau; "
              "the (m,1) family damped less as m grows (less in-plane strain); nothing at "
              "z = 0 (G1 in vacuo, 2 kV, z = 16 mm, g = 2, tau = 0.3 ms: Q = 43, 47, 60 for "
              "(0,1), (1,1), (2,1) at 513-539 Hz and 46 for (0,2) at 1015 Hz; frequencies "
              "+1.2 %, +1.1 %, +1.1 %, +0.8 %; the flat 0.65 m drum head with g = 2, tau = 3 ms: "
              "zeta < 2e-16 and its frequencies unchanged)",
    on_overrides=prony_overrides,
    off_overrides=lambda s: {"membrane.prony": []},
    detect=lambda s: bool(s.membrane.prony),
    needs="quality_factors", fe_role="anchored", visible_in_scan=True, prony_term=True,
    not_direct=("needs the ring surrogate to fit its two parameters (the direct FE engine "
                "would tabulate them on a grid of damped FE solves per condition), which "
                "cannot represent this membrane (no central disc)"),
    # one material-damping cause at a time: the membrane's Prony term (FE) both stiffens and
    # damps, so it stands for the ring model's storage factor (viscoelastic_stiffening) and
    # the paper's hand-calibrated modal b/m (modal_damping) together; it is never tested
    # beside either, nor either beside it (candidates.material_skipped), and it replaces
    # the base's modal b/m (its overrides set reduced.damping_* to 0)
    replaces=("modal_damping",),
    exclusion=Exclusion(("viscoelastic_stiffening", "modal_damping"),
                        rule="one material-damping cause at a time",
                        why="the Prony term would explain the same stiffening or widths",
                        what="the FE's Prony term, which stiffens and damps"),
    switched_keys=("membrane.prony",)))

_register(Effect(
    id="uniform_stiffness", title="uniform membrane stiffening/softening (a parameter effect)",
    description="The membrane is uniformly stiffer or softer than c10, c20, c01 say: electrode "
                "stiffness, pre-stretch loss, a material fit at another rate.  Not missing "
                "physics: a parameter of the study is off.",
    kind="parameter", engine="reduced",
    parameters=(Parameter("scale", "effects.stiffness_scale", None, 1.0, 0.5, 2.0, True,
                          "factor on c10, c20, c01"),),
    signature="every membrane-governed frequency off by about the same factor sqrt(s), at "
              "every z, V_b and mode; P1 less (the spring k_d is not scaled)",
    on_overrides=lambda s, v: {"effects.stiffness_scale": v[0]},
    off_overrides=lambda s: {"effects.stiffness_scale": 1.0},
    detect=lambda s: s.effects.stiffness_scale != 1.0,
    fe_role="anchored", direct=True, visible_in_scan=True, changes_prestress=True))

# -- imperfections of a round device: named from split pairs (diagnosis.imperfections) -----
#: Trial sizes of the FE solves that measure each imperfection's splits (every member kept,
#: however close): large against the 3-D mesh's own split of a perfect pair (< 1e-4), small
#: enough to stay first order (G1 at z = 16 mm, 2 kV: (1,1) split 2.6 % at e = 2 %; a mass
#: shifts its pairs by ~ 0.3 % per 0.5 mg, against the (m,1) family's spacing of 1-4 %).
TRIAL_ANISOTROPY = 0.02
TRIAL_THICKNESS = 0.3
TRIAL_MASS = 5e-7                   # kg: 0.5 mg, ~ 1/800 of G1's film
#: Thickness orders tried: those that split a pair of m <= 2 at first order (k = 2m).
THICKNESS_ORDERS = (2, 4)
#: Radii of the trial masses, as fractions of the membrane's span r_i .. r_o; between them
#: the splits are interpolated linearly (each goes as phi_mn(r)^2, smooth in r).
MASS_RADII = (0.15, 0.4, 0.65, 0.9)


def term_power(order: int):
    """``power(m)`` of :class:`SplitTrial` for a cos k theta term of order ``k``: the members
    of an m pair (orders +-m, 2m apart) are joined at order j = 2m / k of perturbation
    theory where that is an integer, else not at all (module notes of
    :mod:`copdea_fem.diagnosis.imperfections`)."""
    return lambda m: 2.0 * m / order if (2 * m) % order == 0 else None


def _anisotropy_trials(study):
    return (SplitTrial(f"e = {100 * TRIAL_ANISOTROPY:g} % along x",
                       {"membrane.prestretch_anisotropy": TRIAL_ANISOTROPY,
                        "membrane.prestretch_axis": 0.0},
                       TRIAL_ANISOTROPY, term_power(2), 180.0),)


def _thickness_trials(study):
    return tuple(SplitTrial(f"order {k}, a = {TRIAL_THICKNESS:g}",
                            {"membrane.thickness_variation": [
                                {"order": k, "amplitude": TRIAL_THICKNESS, "angle": 0.0}]},
                            TRIAL_THICKNESS, term_power(k), 360.0 / k, (float(k), None, None))
                 for k in THICKNESS_ORDERS)


def _mass_trials(study):
    r_i, r_o = study.geometry.inner_radius, study.geometry.outer_radius
    out = []
    for fraction in MASS_RADII:
        radius = r_i + fraction * (r_o - r_i)
        # a point mass joins every order at first order; phi^2 repeats every 180 / m deg,
        # so a mass at theta and at theta + 180 deg split every pair alike: period 180
        out.append(SplitTrial(f"{TRIAL_MASS * 1e6:g} mg at r = {radius * 1e3:.4g} mm",
                              {"imperfections.point_masses": [
                                  {"mass": TRIAL_MASS, "r": radius, "theta": 0.0}]},
                              TRIAL_MASS, lambda m: 1.0, 180.0, (None, radius, None)))
    return tuple(out)


def _thickness_on(study, values):
    order, amplitude, angle = values
    return {"membrane.thickness_variation": [{"order": round(order),
                                              "amplitude": amplitude, "angle": angle}]}


def _mass_on(study, values):
    mass, radius, theta = values
    return {"imperfections.point_masses": [{"mass": mass, "r": radius, "theta": theta}]}


SPLIT_NOTE = ("named from split (m,n) pairs and their orientations after the search over the "
              "round model (needs model: fe: trial 3-D FE solves); never a candidate of that "
              "search, which cannot split a pair")

_register(Effect(
    id="anisotropic_prestretch", title="anisotropic pre-stretch (an imperfection)",
    description="The film was pre-stretched by lambda_p (1 + e) along an axis and lambda_p "
                "(1 - e) across it, then clamped in the round frame (docs/imperfections.md): "
                "a homogeneous anisotropic stress, a cos 2 (theta - axis) term.  Named from "
                "the split pairs: e from the splits (trial 3-D FE solves at e = 2 %, the "
                "split of each (1,n) pair linear in e, of each (2,n) quadratic), the axis "
                "from the orientation of the stiffer (1,n) member in a scan (its antinode "
                "along the axis); a resonance list gives e only.",
    kind="physics", engine="fe",
    parameters=(Parameter("e", "membrane.prestretch_anisotropy", None, 0.01, 1e-4, 0.3, True,
                          "anisotropy e of the pre-stretch"),
                Parameter("axis", "membrane.prestretch_axis", "deg", 0.0, 0.0, 180.0, False,
                          "direction of the larger pre-stretch, counter-clockwise from x")),
    signature="the (1,n) pairs split at first order in e (G1, z = 16 mm, 2 kV: (1,1) 1.3 % "
              "at e = 1 %), the (2,n) at second order, the (m >= 3, n) hardly; the stiffer "
              "(1,n) member has its antinode along the axis, its partner across it; the "
              "(0,n) modes unmoved at first order",
    on_overrides=lambda s, v: {"membrane.prestretch_anisotropy": v[0],
                               "membrane.prestretch_axis": v[1]},
    off_overrides=lambda s: {"membrane.prestretch_anisotropy": 0.0,
                             "membrane.prestretch_axis": 0.0},
    detect=lambda s: s.membrane.prestretch_anisotropy > 0,
    switched_keys=("membrane.prestretch_anisotropy", "membrane.prestretch_axis"),
    not_tested_note=SPLIT_NOTE,
    split_signature=SplitSignature(_anisotropy_trials, lambda trial, x, angle: (x, angle))))

_register(Effect(
    id="thickness_variation", title="uneven film thickness (an imperfection)",
    description="The film's thickness varies round the device, h0 (1 + a cos k (theta - "
                "angle)) (docs/imperfections.md; an uneven electrode is the same mechanism): "
                "the strain energy and the mass scale with the thickness, the electrostatic "
                "term with its inverse.  Named from the split pairs: the order k (2 or 4) "
                "from which pairs split, a from the splits (trial 3-D FE solves at a = 0.3), "
                "the angle from the orientations in a scan.  Its splits move with the bias "
                "voltage (the electrostatic stress), an anisotropy's hardly: an order-2 term "
                "and an anisotropy that split one bias's pairs alike are told apart by a "
                "condition at another bias.",
    kind="physics", engine="fe",
    parameters=(Parameter("order", "membrane.thickness_variation[0].order", None, 2.0, 1.0,
                          4.0, False, "circumferential order k"),
                Parameter("amplitude", "membrane.thickness_variation[0].amplitude", None,
                          0.05, 1e-3, 0.9, True, "relative amplitude a"),
                Parameter("angle", "membrane.thickness_variation[0].angle", "deg", 0.0, 0.0,
                          180.0, False, "angle of the thickest line")),
    signature="an order-k term splits the m = k/2 pairs at first order (k = 2: the (1,n) "
              "pairs, the (2,n) at second order; k = 4: the (2,n) pairs); odd orders split no "
              "pair at first order; members oriented to the term's angle (period 360/k deg). "
              "In vacuo the film's tension and mass scale together, so the (m,1) pairs "
              "hardly split and the (m,2) carry the evidence, unlike an anisotropy (G1, "
              "z = 16 mm, 2 kV, 3-D FE: order 2, a = 0.3: (1,1) 0.15 %, (1,2) 1.1 %; order 4, "
              "a = 0.3: (2,1) 1.9 %; an anisotropy e = 2 %: (1,1) 2.6 %, (1,2) 2.6 %); in "
              "air the air's added mass does not scale with the film and an order-2 term "
              "splits the (1,1) pair like an anisotropy (coarse mesh, square frame, order 2, "
              "a = 0.2: (1,1) 2.4 % in air, 0.03 % in vacuo), so its trials keep the air; "
              "its splits move with the bias, an anisotropy's hardly (in vacuo, 2 -> 3 kV: "
              "a = 0.2, (1,1) -0.03 % -> -1.27 %; e = 2 %, -2.60 % -> -2.77 %; FE-made scans "
              "in air: 2.45 % -> 3.76 % against 2.74 % -> 2.89 %), so two biases tell them "
              "apart",
    on_overrides=_thickness_on,
    off_overrides=lambda s: {"membrane.thickness_variation": []},
    detect=lambda s: bool(s.membrane.thickness_variation),
    switched_keys=("membrane.thickness_variation",),
    not_tested_note=SPLIT_NOTE,
    split_signature=SplitSignature(_thickness_trials,
                                   lambda trial, x, angle: (trial.fixed[0], x, angle),
                                   magnitude=1, in_air=True, moves_with_bias=True)))

_register(Effect(
    id="point_mass", title="a point mass on the membrane (an imperfection)",
    description="A lumped mass (grease, a wire, a blob of electrode) sits on the membrane "
                "at (r, theta) (docs/imperfections.md).  Named from the split pairs: the "
                "mass and r from the splits of every pair (trial 3-D FE solves of 0.5 mg at "
                "four radii of the membrane, interpolated in r), theta from the orientations "
                "in a scan: the lower member of each pair has its antinode at the mass, the "
                "other its nodal line through it.  At first order a mass at theta and at "
                "theta + 180 deg split every pair alike: theta is given modulo 180 deg.  "
                "A pair a scan shows as one test mode counts against a mass that would "
                "split it past the member's half-power bandwidth 2 zeta (a bounded cost: "
                "the other member may just not be driven).",
    kind="physics", engine="fe",
    parameters=(Parameter("mass", "imperfections.point_masses[0].mass", "kg", 1e-6, 1e-8,
                          1e-3, True, "the lumped mass"),
                Parameter("r", "imperfections.point_masses[0].r", "m", 0.025, 0.0, 1.0,
                          False, "its radius"),
                Parameter("theta", "imperfections.point_masses[0].theta", "deg", 0.0, 0.0,
                          180.0, False, "its angle, counter-clockwise from x (mod 180 deg)")),
    signature="every pair splits at first order, by dm phi_mn(r)^2 / (2 M_modal) (the "
              "(m,1) pairs most for a mass near mid-span, the (m,2) nearly not for one on "
              "their nodal circle), the pair's lower member lowered and oriented to the "
              "mass (its antinode at theta), the upper one unmoved (its nodal line through "
              "the mass); the (0,n) modes lowered too",
    on_overrides=_mass_on,
    off_overrides=lambda s: {"imperfections.point_masses": []},
    detect=lambda s: bool(s.imperfections.point_masses),
    switched_keys=("imperfections.point_masses",),
    not_tested_note=SPLIT_NOTE,
    split_signature=SplitSignature(_mass_trials,
                                   lambda trial, x, angle: (x, trial.fixed[1], angle),
                                   continuous=True)))

EFFECT_IDS = tuple(CATALOGUE)

# The catalogue-level sets, derived from the fields (in catalogue order).
#: Catalogued but tested only when measured.yaml names them in ``candidates``.
OPT_IN = tuple(e.id for e in CATALOGUE.values() if e.opt_in)
#: The imperfections of a round device, named from split pairs
#: (:attr:`Effect.split_signature`, :mod:`copdea_fem.diagnosis.imperfections`).
IMPERFECTIONS = tuple(e.id for e in CATALOGUE.values() if e.split_signature is not None)
#: What the search over the round model may add when measured.yaml lists no ``candidates``
#: (the imperfections are tested after it, from the split pairs).
DEFAULT_CANDIDATES = tuple(e for e in EFFECT_IDS if e not in OPT_IN and e not in IMPERFECTIONS)
#: Mutually exclusive: one mounting at a time.  The base study's own mounting is the
#: starting point; the others are candidates that replace it (candidates.mounting_skipped).
MOUNTINGS = tuple(e.id for e in CATALOGUE.values() if e.mounting is not None)
#: How the FE represents each effect it represents (:attr:`Effect.fe_role`).
FE_ROLES = {e.id: e.fe_role for e in CATALOGUE.values() if e.fe_role is not None}
#: The effects the FE evaluates by itself (:attr:`Effect.direct`).
DIRECT_EFFECTS = tuple(e.id for e in CATALOGUE.values() if e.direct)
#: The effects a synthetic vibrometer export can hide (:attr:`Effect.visible_in_scan`).
SCAN_EFFECTS = tuple(e.id for e in CATALOGUE.values() if e.visible_in_scan)
#: Parameters an FE engine does not read (:attr:`Parameter.surrogate_only`).
SURROGATE_ONLY_KEYS = tuple(p.key for e in CATALOGUE.values() for p in e.parameters
                            if p.surrogate_only)
#: Study keys (or key prefixes) a measured.yaml condition may not set -> the effect that
#: switches them (:attr:`Effect.switched_keys`).
SWITCHED_KEYS = {key: e.id for e in CATALOGUE.values() for key in e.switched_keys}


def _the_air_effect() -> Effect:
    air = [e for e in CATALOGUE.values() if e.adds_air]
    if len(air) != 1:
        raise ValueError(f"adds_air = {[e.id for e in air]!r} is not allowed; allowed: "
                         "exactly one effect of the catalogue")
    return air[0]


#: The effect that puts the air in the model (:attr:`Effect.adds_air`).
AIR_EFFECT = _the_air_effect()


def _check_references() -> None:
    """Every effect an effect names (requires, replaces, excludes) is catalogued."""
    for e in CATALOGUE.values():
        named = e.requires + e.replaces + (e.exclusion.effects if e.exclusion else ())
        unknown = [n for n in named if n not in CATALOGUE]
        if unknown:
            raise ValueError(f"effect {e.id}: {', '.join(unknown)} is not allowed (unknown "
                             f"effect); allowed: {', '.join(EFFECT_IDS)}")


_check_references()


def base_mounting(study) -> str | None:
    """The mounting effect a study states (:data:`MOUNTINGS`): ``enclosure`` for a
    ``geometry.enclosure`` other than none, else ``open_air`` for ``geometry.frame: none``,
    ``baffle``, ``frame_reflection`` for a square or circle."""
    return next((m for m in MOUNTINGS if CATALOGUE[m].is_on(study)), None)


def effect(effect_id: str) -> Effect:
    """The catalogue entry of an identifier; :class:`StudyError` names the allowed ones."""
    try:
        return CATALOGUE[effect_id]
    except KeyError:
        raise StudyError(f"effect = {effect_id!r} is not allowed (unknown effect); allowed: "
                         + ", ".join(EFFECT_IDS)) from None


def parse_effect_list(text, key: str = "--effects") -> tuple:
    """``"air_loading, spring_mass"`` (or a list) -> validated identifiers, in order."""
    items = text if isinstance(text, (list, tuple)) else str(text).split(",")
    names = [str(item).strip() for item in items if str(item).strip()]
    for name in names:
        if name not in CATALOGUE:
            raise StudyError(f"{key} = {name!r} is not allowed (unknown effect); allowed: "
                             + ", ".join(EFFECT_IDS))
    if len(set(names)) != len(names):
        raise StudyError(f"{key} = {text!r} is not allowed; allowed: each effect once")
    return tuple(names)


def catalogue_table() -> str:
    """Markdown table of the catalogue (README, ``copdea-fem effects``)."""
    rows = ["| id | kind | engine | parameters (default, fit bounds) | signature |",
            "|---|---|---|---|---|"]
    for e in CATALOGUE.values():
        params = "; ".join(f"{p.name} `{p.key}` {p.shown(p.default)} [{p.shown(p.lower)}, "
                           f"{p.shown(p.upper)}]" for p in e.parameters) or "none"
        engine = e.engine + {"coupled_fe": " (FE solves; needs model: fe and air)",
                             "fe": " (FE solves; needs model: fe)"}.get(e.engine, "")
        if e.opt_in:
            engine += "; opt-in: tested only where measured.yaml's candidates name it"
        if e.split_signature is not None:
            engine += "; named from split pairs after the search"
        rows.append(f"| `{e.id}` | {e.kind} | {engine} | {params} | {e.signature} |")
    return "\n".join(rows)


#: What ``measured.yaml`` may say of the effects, for its reader
#: (:func:`copdea_fem.measured.load_measured`): ``candidates:`` read by
#: :func:`parse_effect_list`, :data:`DEFAULT_CANDIDATES` without it; a condition may not set
#: the ``effects.`` section nor a key of :data:`SWITCHED_KEYS`.
MANIFEST_RULES = EffectRules(parse_candidates=parse_effect_list,
                             default_candidates=DEFAULT_CANDIDATES,
                             switched_keys={"effects.": "the effects", **SWITCHED_KEYS})
