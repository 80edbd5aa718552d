"""The checks across keys, after each key was read alone: derived defaults, the geometry,
the mesh, the enclosure, the reduced model's keys, and the compound text keys
(``reduced.modes``, ``response.microphones``) read and checked.
"""

from __future__ import annotations

import math
from typing import Any

from copdea_fem.study.keys import above, apart, convert_quantity, refusal
from copdea_fem.study.schema import (
    AXISYMMETRIC_FRAMES,
    ENCLOSURE_AIR_SHARE,
    ENCLOSURE_MIN_DEPTH,
    ENCLOSURE_MIN_GAP,
    MAX_ELEMENTS_ACROSS,
)
from copdea_fem.study.imperfections import (
    check_imperfections,
    imperfection_keys_given,
    perturbation_refusal,
)
from copdea_fem.study.segments import check_segments


def derived_defaults(v: dict[str, dict[str, Any]], name: str) -> None:
    """Fill in, in place, the defaults computed from other keys (a
    :class:`~copdea_fem.study.keys.Key` with ``derived``): the air sphere, PML and air mesh
    from r_o, the circular frame's radius, the enclosure's depth and radius, the output
    folder (from the study's ``name``)."""
    r_o = v["geometry"]["outer_radius"]
    for section, key, factor in (("air", "domain_radius", 3.5), ("air", "pml_thickness", 0.5),
                                 ("mesh", "air_size", 0.5)):
        if v[section][key] is None:
            v[section][key] = factor * r_o
    if v["geometry"]["frame_radius"] is None:
        v["geometry"]["frame_radius"] = 0.5 * v["geometry"]["frame_side"]
    g = v["geometry"]
    for key, default in enclosure_defaults(g).items():
        if g[key] is None:
            g[key] = default
    if v["output"]["directory"] is None:
        v["output"]["directory"] = f"results/{name}"



def enclosure_defaults(g) -> dict[str, float]:
    """The enclosure's keys when the study leaves them out (``g``: the geometry section,
    SI): as deep as r_o, as wide as r_o - under a circular frame the whole ring is its lid -
    and no vent."""
    get = g.__getitem__ if isinstance(g, dict) else lambda key: getattr(g, key)
    r_o = get("outer_radius")
    return {"enclosure_depth": r_o,
            "enclosure_radius": get("frame_radius") if get("frame") == "circle" else r_o,
            "enclosure_vent_radius": 0.0}

def check_across_keys(v: dict[str, dict[str, Any]]) -> None:
    """The checks that need more than one key, on the values read key by key (SI, defaults
    filled in); a :class:`~copdea_fem.study.keys.StudyError` names the key to change."""
    g, load = v["geometry"], v["load"]
    r_o, r_i = g["outer_radius"], g["inner_radius"]
    if not above(r_o, r_i):
        raise refusal("geometry.inner_radius", r_i, f"[0, {r_o:g}) m = below geometry.outer_radius")
    if 0 < r_i < 0.02 * r_o:
        raise refusal("geometry.inner_radius", r_i, f"0 or >= {0.02 * r_o:g} m (2 % of r_o)",
                      "a disc this small cannot be meshed sensibly")
    if g["frame"] == "square" and not above(g["frame_side"], 2 * r_o):
        raise refusal("geometry.frame_side", g["frame_side"],
                      f"> {2 * r_o:g} m = the membrane diameter 2 * geometry.outer_radius")
    R = v["air"]["domain_radius"]
    if g["frame"] == "square" and not above(R, g["frame_side"] / math.sqrt(2)):
        raise refusal("air.domain_radius", R, f"> {g['frame_side'] / math.sqrt(2):g} m",
                      "the square frame's corners must lie inside the air sphere")
    if not above(R, 1.2 * r_o):
        raise refusal("air.domain_radius", R, f"> {1.2 * r_o:g} m = 1.2 * geometry.outer_radius")
    width = r_o - r_i
    smallest = width / MAX_ELEMENTS_ACROSS
    if g["frame"] == "circle" and not (above(g["frame_radius"], r_o)
                                       and above(R, g["frame_radius"])):
        raise refusal("geometry.frame_radius", g["frame_radius"],
                      f"({r_o:g}, {R:g}) m = between geometry.outer_radius and air.domain_radius")
    if g["frame"] == "circle" and g["frame_radius"] - r_o < smallest:
        raise refusal("geometry.frame_radius", g["frame_radius"],
                      f">= {r_o + smallest:g} m = geometry.outer_radius + (r_o - r_i) / "
                      f"{MAX_ELEMENTS_ACROSS}", "a frame ring this narrow cannot be meshed")
    engine = v["mesh"]["engine"]
    if engine == "axisymmetric" and g["frame"] not in AXISYMMETRIC_FRAMES:
        raise refusal("mesh.engine", engine, f"3d or auto with geometry.frame = {g['frame']}",
                      "the axisymmetric engine needs frame none, baffle or circle")
    if engine == "3d" and g["frame"] == "circle":
        raise refusal("mesh.engine", engine, "axisymmetric or auto with geometry.frame = circle",
                      "the 3-D mesh has no circular frame")
    _check_enclosure(v)
    if r_i == 0:
        if load["z"] != 0:
            raise refusal("load.z", load["z"], "0 m when geometry.inner_radius = 0",
                          "a full membrane has no disc to displace")
        if v["disc"]["motion"] != "held":
            raise refusal("disc.motion", v["disc"]["motion"], "held when geometry.inner_radius = 0",
                          "a full membrane has no disc")
    if load["z"] > 2 * (r_o - r_i):
        raise refusal("load.z", load["z"], f"[0, {2 * (r_o - r_i):g}] m = 2 * (r_o - r_i)",
                      "meridian stretch beyond what the film survives")
    e = v["eigen"]
    if not above(e["f_max"], e["f_min"]):
        raise refusal("eigen.f_max", e["f_max"], f"> eigen.f_min = {e['f_min']:g} Hz")
    prony = v["membrane"]["prony"]
    if prony:
        # the rational eigen problem's relaxation spectrum lies on Re f = 0 from
        # |Im f| = 1/(2 pi tau_max (1 + sum g)) (copdea_fem.fe.eigen.damped): keep it out of
        # the band
        lowest = 1.0 / (2 * math.pi * max(t["relaxation_time"] for t in prony)
                        * (1 + sum(t["modulus_ratio"] for t in prony)))
        height = e["max_damping_ratio"] * e["f_max"]
        if e["f_min"] < 0.5 * lowest and lowest <= 2 * height:
            raise refusal("eigen.f_min", e["f_min"], f">= {0.5 * lowest:.4g} Hz with this "
                          "membrane.prony", f"the Prony relaxation spectrum (Re f = 0, |Im f| >= "
                          f"{lowest:.4g} Hz) would reach the band |Im f| <= eigen.max_damping_ratio"
                          f" * eigen.f_max = {height:.4g} Hz")
    if v["mesh"]["membrane_size"] > width / 2:
        raise refusal("mesh.membrane_size", v["mesh"]["membrane_size"],
                      f"<= {width / 2:g} m = half the membrane width",
                      "fewer than two elements across the membrane")
    if v["mesh"]["membrane_size"] < smallest:
        raise refusal("mesh.membrane_size", v["mesh"]["membrane_size"],
                      f">= {smallest:g} m = (r_o - r_i) / {MAX_ELEMENTS_ACROSS}",
                      f"more than {MAX_ELEMENTS_ACROSS} elements across the membrane: Netgen "
                      "cannot mesh it")
    _check_reduced_keys(v)
    listed_microphones(v["response"]["microphones"], g["frame"], g["enclosure"])
    check_segments(v)
    check_imperfections(v)
    imperfect = imperfection_keys_given(v["membrane"], v["imperfections"])
    beyond = imperfect and perturbation_refusal(v["membrane"], v["imperfections"],
                                                v["geometry"])
    if beyond and engine == "axisymmetric":
        key, value, allowed = beyond
        raise refusal(key, value, allowed + ", or mesh.engine: 3d (or auto)",
                      "mesh.engine = axisymmetric takes an imperfection by first-order "
                      "perturbation only")
    if beyond and g["frame"] == "circle":
        raise refusal("geometry.frame", g["frame"], "square, baffle or none with " + imperfect,
                      "an imperfect device needs the 3-D engine, which has no circular frame")
    m = v["membrane"]
    if v["response"]["method"] == "reduced_modal" and (
            m["loss_factor"] > 0 or m["rayleigh_alpha"] > 0 or m["rayleigh_beta"] > 0
            or m["prony"]):
        raise refusal("response.method", "reduced_modal", "auto, modal, direct or reduced with a "
                      "loss of the membrane's own (membrane.loss_factor, rayleigh_alpha, "
                      "rayleigh_beta or prony)", "the reduced basis's modes would not "
                      "diagonalise that loss")


def _check_enclosure(v: dict[str, dict[str, Any]]) -> None:
    """Cross-key checks of geometry.enclosure* and air.outside (docs/enclosures.md)."""
    g, air = v["geometry"], v["air"]
    enclosure, frame = g["enclosure"], g["frame"]
    if enclosure == "none":
        if not air["outside"]:
            raise refusal("air.outside", False, "true with geometry.enclosure = none",
                          "without an enclosure there is no air but the outside air")
        return
    r_o, depth, vent = g["outer_radius"], g["enclosure_depth"], g["enclosure_vent_radius"]
    if above(ENCLOSURE_MIN_DEPTH * r_o, depth):
        raise refusal("geometry.enclosure_depth", depth,
                      f">= {ENCLOSURE_MIN_DEPTH * r_o:g} m = {ENCLOSURE_MIN_DEPTH:g} * "
                      "geometry.outer_radius", "a thinner gap cannot be meshed sensibly")
    if enclosure == "box":
        if frame != "square":
            raise refusal("geometry.enclosure", enclosure, "cylinder or bowl with geometry.frame "
                          f"= {frame}", "a box sits under the square frame (frame: square)")
        half_width = 0.5 * g["frame_side"]
        farthest = math.hypot(half_width * math.sqrt(2), depth)
    else:
        radius = g["enclosure_radius"]
        if above(r_o, radius):
            raise refusal("geometry.enclosure_radius", radius,
                          f">= {r_o:g} m = geometry.outer_radius",
                          "the enclosure's rim is sealed to the membrane's rim")
        if frame == "circle" and apart(radius, g["frame_radius"]):
            raise refusal("geometry.enclosure_radius", radius,
                          f"{g['frame_radius']:g} m = geometry.frame_radius (its default with "
                          "frame circle)", "the enclosure sits under the circular frame, which "
                          "is its lid: a ring reaching past the enclosure's rim would need a "
                          "pressure jump outside the cavity, which the axisymmetric engine "
                          "does not carry")
        if frame == "square" and not above(0.5 * g["frame_side"], radius):
            raise refusal("geometry.enclosure_radius", radius,
                          f"< {0.5 * g['frame_side']:g} m = half geometry.frame_side",
                          "the enclosure sits under the square frame")
        if enclosure == "bowl" and above(depth, radius):
            raise refusal("geometry.enclosure_depth", depth,
                          f"(0, {radius:g}] m = at most geometry.enclosure_radius",
                          "a bowl is a spherical cap, at most a hemisphere")
        half_width = radius
        farthest = math.hypot(radius, depth)
    if not above(half_width, vent):
        raise refusal("geometry.enclosure_vent_radius", vent,
                      f"[0, {half_width:g}) m = narrower than the enclosure's bottom")
    if enclosure != "box":
        _check_enclosure_radii(g, vent, r_o)
    if vent > 0 and frame == "baffle":
        raise refusal("geometry.enclosure_vent_radius", vent, "0 with geometry.frame = baffle",
                      "with a baffle the enclosure replaces the lower half-space: no outside "
                      "air for the vent to open to")
    if vent > 0 and not air["outside"]:
        raise refusal("geometry.enclosure_vent_radius", vent, "0 with air.outside = false",
                      "a vent opens to the outside air")
    if not air["outside"] and not air["enabled"]:
        raise refusal("air.outside", False, "true when air.enabled = false",
                      "there is no air to keep")
    R = air["domain_radius"]
    if frame == "baffle" and above(half_width, ENCLOSURE_AIR_SHARE * R):
        raise refusal("air.domain_radius", R, f">= {half_width / ENCLOSURE_AIR_SHARE:g} m",
                      f"the enclosure's top (radius {half_width:g} m) must lie within "
                      f"{ENCLOSURE_AIR_SHARE:g} of the air sphere's radius")
    if frame != "baffle" and air["outside"] and above(farthest, ENCLOSURE_AIR_SHARE * R):
        raise refusal("air.domain_radius", R, f">= {farthest / ENCLOSURE_AIR_SHARE:g} m",
                      f"the enclosure's farthest point ({farthest:g} m from the centre) must lie "
                      f"within {ENCLOSURE_AIR_SHARE:g} of the air sphere's radius, with outside "
                      "air around it")


def _check_enclosure_radii(g: dict[str, Any], vent: float, r_o: float) -> None:
    """The radii where the meridian's lines meet: equal or :data:`ENCLOSURE_MIN_GAP` r_o
    apart (a vent of 0 is none; the frame's only with frame circle)."""
    gap = ENCLOSURE_MIN_GAP * r_o
    radii = {"geometry.inner_radius": g["inner_radius"], "geometry.outer_radius": r_o,
             "geometry.enclosure_radius": g["enclosure_radius"]}
    if g["frame"] == "circle":
        radii["geometry.frame_radius"] = g["frame_radius"]
    if 0 < vent < gap:
        raise refusal("geometry.enclosure_vent_radius", vent,
                      f"0 or >= {gap:g} m = {ENCLOSURE_MIN_GAP:g} * geometry.outer_radius",
                      "a smaller vent cannot be meshed")
    for name, radius in radii.items():
        if radius > 0 and vent > 0 and apart(vent, radius) and abs(vent - radius) < gap:
            raise refusal("geometry.enclosure_vent_radius", vent, f"equal to {name} = "
                          f"{radius:g} m or at least {gap:g} m from it",
                          "the lines meeting there cannot be meshed")
    for name in ("geometry.enclosure_radius", "geometry.frame_radius"):
        if name not in radii:
            continue
        for other, radius in radii.items():
            if other != name and apart(radii[name], radius) and abs(radii[name] - radius) < gap:
                raise refusal(name, radii[name], f"equal to {other} = {radius:g} m or at least "
                              f"{gap:g} m from it", "the lines meeting there cannot be meshed")


def reduced_mode_labels(text: str, disc_motion: str) -> tuple[str, ...]:
    """Labels of ``reduced.modes``: ``"auto"`` or a comma-separated list of P1 and (0,n)."""
    import re
    if text.strip() == "auto":
        return (("P1",) if disc_motion == "spring" else ()) + ("(0,1)", "(0,2)")
    allowed = "auto, or a comma-separated list of P1 and (0,n) with n >= 1, e.g. 'P1, (0,1), (0,2)'"
    labels = []
    for item in re.findall(r"\([^)]*\)|[^,\s()]+", text):
        match = re.fullmatch(r"\(\s*0\s*,\s*([1-9]\d*)\s*\)", item)
        if match:
            labels.append(f"(0,{match.group(1)})")
        elif item.upper() == "P1":
            labels.append("P1")
        elif item:
            raise refusal("reduced.modes", text, allowed, f"cannot read {item!r}")
    if not labels or len(set(labels)) != len(labels):
        raise refusal("reduced.modes", text, allowed, "empty or repeated labels")
    if "P1" in labels and disc_motion != "spring":
        raise refusal("reduced.modes", text, "labels without P1 when disc.motion = held",
                      "the pumping mode needs the disc on the spring")
    return tuple(labels)


MICROPHONES_ALLOWED = "'name = x, y, z; ...' with lengths, e.g. 'side = 0.5 m, 0 m, 0.5 m'"
#: The name of the default microphone (on the +z axis at ``response.microphone_distance``);
#: a microphone of ``response.microphones`` may not take it.
DEFAULT_MICROPHONE = "axis"


def listed_microphones(text: str, frame: str = "square",
                       enclosure: str = "none") -> list[tuple[str, tuple[float, float, float]]]:
    """The microphones of ``response.microphones`` (``"name = x, y, z; ..."``, units
    allowed, a bare number in m): named positions (x, y, z) [m], checked.

    Refused (key ``response.microphones``): an item that is not ``name = x, y, z`` (a name of
    letters, digits and ``_``; three coordinates), a name given twice (the default
    microphone's, :data:`DEFAULT_MICROPHONE`, included), a coordinate that is not a length
    in [-1e4, 1e4] m, a point at the origin (the membrane's centre), and with
    ``frame = "baffle"`` a point on the rigid plane z = 0 (the Rayleigh integral is taken on
    the microphone's side of the baffle), and with a baffle over an enclosure a point
    below it (z < 0: the enclosure replaces the lower half-space).  Called when a study is read, so a bad list never
    reaches a solve; the forced response adds the default microphone
    (:func:`copdea_fem.forced_response.run.parse_microphones`).
    """
    key = "response.microphones"
    microphones = []
    names = {DEFAULT_MICROPHONE}
    text = text or ""
    for item in filter(None, (part.strip() for part in text.split(";"))):
        name, _, coordinates = item.partition("=")
        name = name.strip()
        values = [part.strip() for part in coordinates.split(",")]
        if not name or not name.replace("_", "").isalnum() or len(values) != 3:
            raise refusal(key, text, MICROPHONES_ALLOWED, f"cannot read {item!r}")
        if name in names:
            raise refusal(key, text, f"{MICROPHONES_ALLOWED} with distinct names",
                          f"microphone {name!r} repeated")
        position = tuple(convert_quantity(key, _number_or_text(value), "m", -1e4, 1e4)
                         for value in values)
        if not any(position):
            raise refusal(key, text, "a point away from the membrane centre",
                          f"microphone {name!r} at the origin")
        if frame == "baffle" and enclosure != "none" and position[2] < 0:
            raise refusal(key, text, "z > 0 with geometry.frame = baffle over an enclosure",
                          f"microphone {name!r} at z < 0 lies inside the enclosure's "
                          f"half-space (position {list(position)} m)")
        if frame == "baffle" and position[2] == 0:
            raise refusal(key, text, "z != 0 with geometry.frame = baffle", f"microphone {name!r} "
                          f"at z = 0 lies on the rigid plane (position {list(position)} m)")
        microphones.append((name, position))
        names.add(name)
    return microphones


def _number_or_text(text: str):
    """A bare number is in SI (m), as everywhere in a study; else a quantity with a unit."""
    try:
        return float(text)
    except ValueError:
        return text


def _check_reduced_keys(v: dict[str, dict[str, Any]]) -> None:
    """Cross-key checks of the ``reduced`` and ``excitation`` sections."""
    labels = reduced_mode_labels(v["reduced"]["modes"], v["disc"]["motion"])
    orders = [int(label[3:-1]) for label in labels if label != "P1"]
    rings = v["reduced"]["rings"]
    if orders and max(orders) > rings - 1:
        raise refusal("reduced.rings", rings, f">= {max(orders) + 1}",
                      f"(0,{max(orders)}) needs at least {max(orders) + 1} rings")
    x = v["excitation"]
    if x["f_end"] <= x["f_start"]:
        raise refusal("excitation.f_end", x["f_end"], f"> excitation.f_start = {x['f_start']:g} Hz")
    nyquist = 0.5 / x["sample_time"]
    if x["f_end"] > nyquist:
        raise refusal("excitation.f_end", x["f_end"], f"<= {nyquist:g} Hz = 1 / (2 "
                      "excitation.sample_time)", "above the Nyquist frequency")
    samples = x["duration"] / x["sample_time"]
    if abs(samples - round(samples)) > 1e-6 * samples or not 4 <= round(samples) <= 10_000_000:
        raise refusal("excitation.duration", x["duration"], "an integer multiple (4 to 1e7) of "
                      f"excitation.sample_time = {x['sample_time']:g} s")
    if x["f_end"] * x["duration"] < 1:
        raise refusal("excitation.f_end", x["f_end"], f">= {1 / x['duration']:g} Hz = "
                      "1 / excitation.duration", "no spectral line in the band")
