"""The segmented electrode of a study: the key ``electrodes.segments`` read item by item
(:func:`read_segments`) and checked against the membrane and each other
(:func:`check_segments`).

A segment is an annular sector of the membrane's electrode, ``theta`` in
``[from, to]`` (degrees counter-clockwise from the x axis; ``from > to`` wraps through 0,
``[0, 360]`` is the whole circle) and ``r`` in ``[from, to]`` (metres on the flat
pre-stretched reference; none = the whole membrane annulus ``[r_i, r_o]``), driven by
``drive.amplitude`` AC volts per volt of the input [V/V] at ``drive.phase`` [deg].  All
segments share the bias ``load.voltage``; the forcing of each is that of its indicator as a
weight on the co-energy (:mod:`copdea_fem.fe.forced.electrode`).  Angles stay in degrees in
the resolved study (the unit of the key, so that a resolved study reads back as it was
written); the weight converts them to radians.
"""

from __future__ import annotations

from typing import Any

from copdea_fem.study.keys import above, convert_quantity, refusal

#: Most segments a study may hold (each is one forcing vector per driven part).
MAX_SEGMENTS = 64
SEGMENTS_ALLOWED = (f"a list of at most {MAX_SEGMENTS} mappings {{name: text, theta: [from, to] "
                    "in degrees, r: [from, to] in metres (optional, default the whole "
                    "membrane), drive: {amplitude: AC volts per volt of input (default 1), "
                    "phase: degrees (default 0)} (optional)}")
SEGMENT_KEYS = {"name", "theta", "r", "drive"}
DRIVE_KEYS = {"amplitude", "phase"}


def _pair(where: str, value: Any, unit: str, lo: float, hi: float) -> list[float]:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise refusal(where, value, f"a list [from, to] of two values in {unit}")
    return [convert_quantity(f"{where}[{i}]", item, unit, lo, hi)
            for i, item in enumerate(value)]


def read_segments(key: str, value: Any) -> list:
    """``electrodes.segments`` (mappings or
    :class:`~copdea_fem.study.sections.ElectrodeSegment`) -> ``[{"name", "theta": [from, to]
    [deg], "r": [from, to] [m] or None, "drive": {"amplitude" [V/V], "phase" [deg]}}, ...]``;
    each value read and bounded alone (the checks across segments: :func:`check_segments`)."""
    if value is None:
        value = []
    if not isinstance(value, (list, tuple)) or len(value) > MAX_SEGMENTS:
        raise refusal(key, value, SEGMENTS_ALLOWED)
    segments = []
    for index, item in enumerate(value):
        where = f"{key}[{index}]"
        if hasattr(item, "plain"):                      # an ElectrodeSegment
            item = item.plain()
        if not isinstance(item, dict) or not {"name", "theta"} <= set(item) \
                or not set(item) <= SEGMENT_KEYS:
            raise refusal(where, item, SEGMENTS_ALLOWED, "each segment needs the keys name "
                          "and theta, and may have r and drive")
        name = item["name"]
        if not isinstance(name, str) or not name.strip() or name != name.strip() \
                or any(c in name for c in ",\n\"'"):
            raise refusal(f"{where}.name", name, "a non-empty text without commas, quotes, "
                          "line breaks or surrounding spaces")
        theta = _pair(f"{where}.theta", item["theta"], "deg", -360.0, 360.0)
        radii = item.get("r")
        r = None if radii is None else _pair(f"{where}.r", radii, "m", 0.0, 1.0)
        drive = item.get("drive") or {}
        if not isinstance(drive, dict) or not set(drive) <= DRIVE_KEYS:
            raise refusal(f"{where}.drive", drive, "a mapping {amplitude: V/V, phase: degrees}")
        amplitude = convert_quantity(f"{where}.drive.amplitude", drive.get("amplitude", 1.0),
                                     "", -1e3, 1e3)
        phase = convert_quantity(f"{where}.drive.phase", drive.get("phase", 0.0), "deg",
                                 -360.0, 360.0)
        segments.append({"name": name, "theta": theta, "r": r,
                         "drive": {"amplitude": amplitude, "phase": phase}})
    return segments


def angular_span(theta: list[float]) -> float:
    """The angle [deg] a segment's ``theta = [from, to]`` covers counter-clockwise from
    ``from`` to ``to`` (through 0 where ``to < from``); 0 for an empty segment, 360 for
    ``to - from = 360``."""
    start, end = theta
    if end - start >= 360.0:
        return 360.0
    return (end - start) % 360.0


def _arcs_overlap(first: list[float], second: list[float]) -> bool:
    """Whether two arcs [deg] share an angle of positive measure (module notes)."""
    span_a, span_b = angular_span(first), angular_span(second)
    if span_a >= 360.0 or span_b >= 360.0:
        return True
    offset = (second[0] - first[0]) % 360.0         # where the second starts, from the first's
    return (offset < span_a and above(span_a, offset)) or \
        (360.0 - offset < span_b and above(span_b, 360.0 - offset))


def check_segments(v: dict[str, dict[str, Any]]) -> None:
    """The segments against the membrane and each other: names distinct, no empty segment
    (``theta`` or ``r`` of zero width), radii on the membrane annulus ``[r_i, r_o]``, no two
    segments sharing an area; a :class:`~copdea_fem.study.keys.StudyError` names the
    segment."""
    segments = v["electrodes"]["segments"]
    r_o, r_i = v["geometry"]["outer_radius"], v["geometry"]["inner_radius"]
    seen: dict[str, int] = {}
    for index, segment in enumerate(segments):
        where = f"electrodes.segments[{index}] ({segment['name']})"
        if segment["name"] in seen:
            raise refusal(f"{where}.name", segment["name"], "a name no other segment has",
                          f"segment {seen[segment['name']]} has it too")
        seen[segment["name"]] = index
        if angular_span(segment["theta"]) == 0.0:
            raise refusal(f"{where}.theta", segment["theta"], "[from, to] degrees covering a "
                          "positive angle (to - from not a multiple of 360, or exactly 360)",
                          "an empty segment")
        if segment["r"] is not None:
            inner, outer = segment["r"]
            if inner < r_i and above(r_i, inner) or outer > r_o and above(outer, r_o):
                raise refusal(f"{where}.r", segment["r"], f"[from, to] within the membrane "
                              f"annulus [{r_i:g}, {r_o:g}] m (geometry.inner_radius, "
                              "geometry.outer_radius)", "off the membrane")
            if not above(outer, inner):
                raise refusal(f"{where}.r", segment["r"], "[from, to] metres with from < to",
                              "an empty segment")
    for index, segment in enumerate(segments):
        for other in range(index):
            if _segments_overlap(segments[other], segment, r_i, r_o):
                raise refusal(f"electrodes.segments[{index}] ({segment['name']})",
                              f"theta {segment['theta']}, r {segment['r']}",
                              "segments that share no area",
                              f"it overlaps segment {other} ({segments[other]['name']})")


def _segments_overlap(first: dict, second: dict, r_i: float, r_o: float) -> bool:
    (a_in, a_out), (b_in, b_out) = first["r"] or (r_i, r_o), second["r"] or (r_i, r_o)
    radial = above(min(a_out, b_out), max(a_in, b_in))
    return radial and _arcs_overlap(first["theta"], second["theta"])


def whole_turn(theta: list[float]) -> bool:
    """Whether ``theta = [from, to]`` [deg] covers the whole circle."""
    return angular_span(theta) >= 360.0


__all__ = ["MAX_SEGMENTS", "SEGMENTS_ALLOWED", "angular_span", "check_segments", "read_segments",
           "whole_turn"]

