"""Blind battery of the diagnosis with the mounting hidden, on data the FE made (issue 24).

The "measured" resonances are FE frequencies with the noise of ``fe_battery.py``
(1 % log-normal scatter, 10 % missed, Poisson(0.3) spurious peaks per condition,
half the labels, kinds unknown when unlabelled; its generator, not ``synth``'s).
Cases: the paper's G1 (disc held, coupled with air) open in air vs in an infinite
baffle, and a disc-less drum head -- the 0.65 m Mylar head of
``studies/drum_mylar_650mm.yaml`` on a coarse mesh (40 mm, the axisymmetric engine,
~1 s a solve) at three tensions (pre-stretch 1.03, 1.05, 1.08: a head re-tuned,
like a timpani), open in air vs baffled or in a square frame (3-D quadrant solves),
with its tension known or not.  A drum
head struck off-centre shows its (m,1) modes: orders m <= 4 are seen.

FE solves are cached in ``tests/data/fe_cache`` (keyed by the FE study's hash):
fill it with ``python tests/diagnosis/mount_battery.py`` (axisymmetric solves only,
about a minute); the diagnosis reads the same entries.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))

import fe_battery  # noqa: E402

from copdea_fem.diagnosis.effects import MOUNTINGS  # noqa: E402
from copdea_fem.diagnosis.fe import BAND_MARGIN, FEModel  # noqa: E402
from copdea_fem.study import parse_study  # noqa: E402

FE_CACHE = fe_battery.FE_CACHE

DRUM = {"name": "drum_open", "description": "0.65 m Mylar drum head, open in air (coarse)",
        "geometry": {"outer_radius": "325 mm", "inner_radius": "0 mm", "frame": "none"},
        "membrane": {"thickness": "0.2095 mm", "prestretch": 1.05, "density": "1380 kg/m^3",
                     "c10": "18.81 MPa", "c20": "0 Pa", "c01": "0 Pa"},
        "air": {"enabled": True}, "mesh": {"membrane_size": "40 mm"},
        "output": {"plots": False}}
DRUM_BAFFLED = fe_battery._with(DRUM, geometry={"frame": "baffle"})
DRUM_STIFFER = fe_battery._with(DRUM, effects={"stiffness_scale": 1.1})   # tension +10 %
DRUM_STIFFER_BAFFLED = fe_battery._with(DRUM_BAFFLED, effects={"stiffness_scale": 1.1})
# the square frame frame_reflection puts round the head: G1's proportion, side 1.13 x 0.65 m
DRUM_FRAMED = fe_battery._with(DRUM, geometry={"frame": "square",
                                               "frame_side": 0.080 / 0.071 * 0.65})
# a sealed cylinder of the head's radius under it, 0.6 r_o = 195 mm deep, in free air: what
# the catalogue's enclosure puts there (geometry.frame none, cylinder, sealed)
ENCLOSURE_DEPTH_RATIO = 0.6
DRUM_ENCLOSED = fe_battery._with(DRUM, geometry={
    "enclosure": "cylinder", "enclosure_depth": ENCLOSURE_DEPTH_RATIO * 0.325,
    "enclosure_radius": 0.325})
DRUM_TENSIONS = [{"membrane.prestretch": p} for p in (1.03, 1.05, 1.08)]
DRUM_BAND = (30.0, 350.0)         # Hz: (0,1) of the slackest head to (4,1) of the tautest

G1_OPEN = fe_battery._with(fe_battery.DRY, air={"enabled": True}, geometry={"frame": "none"})
G1_BAFFLED = fe_battery._with(G1_OPEN, geometry={"frame": "baffle"})
G1_ENCLOSED = fe_battery._with(G1_OPEN, geometry={
    "enclosure": "cylinder", "enclosure_depth": ENCLOSURE_DEPTH_RATIO * 0.0355,
    "enclosure_radius": 0.0355})


@dataclass(frozen=True)
class Case:
    """Base model, the FE study that makes the data, conditions, band, seen orders, and the
    right verdict: ``missing`` in any order; ``ambiguous_ok``: effects that may stand in an
    ambiguous group together with a hidden mounting instead of being named."""

    base: dict
    truth: dict
    conditions: list
    band: tuple
    orders: int
    missing: tuple
    ambiguous_ok: tuple = ()
    candidates: tuple = ()        # measured.yaml's candidates (empty: the default list)


CASES = {
    "g1_baffle_hidden": Case(G1_OPEN, G1_BAFFLED, fe_battery.AIR5, fe_battery.BAND, 2,
                             ("baffle",)),
    "g1_open_null": Case(G1_OPEN, G1_OPEN, fe_battery.AIR5, fe_battery.BAND, 2, ()),
    "drum_baffle_hidden": Case(DRUM, DRUM_BAFFLED, DRUM_TENSIONS, DRUM_BAND, 4, ("baffle",)),
    "drum_open_null": Case(DRUM, DRUM, DRUM_TENSIONS, DRUM_BAND, 4, ()),
    "drum_frame_hidden": Case(DRUM, DRUM_FRAMED, DRUM_TENSIONS, DRUM_BAND, 4,
                              ("frame_reflection",)),
}
# The reverse direction (issue 24): a base that states a mounting the truth lacks -- open-air
# data diagnosed from a baffled base -- and its null sets (baffled data, baffled base).
REVERSE_CASES = {
    "g1_open_hidden": Case(G1_BAFFLED, G1_OPEN, fe_battery.AIR5, fe_battery.BAND, 2,
                           ("open_air",)),
    "g1_baffle_null": Case(G1_BAFFLED, G1_BAFFLED, fe_battery.AIR5, fe_battery.BAND, 2, ()),
    "drum_open_hidden": Case(DRUM_BAFFLED, DRUM, DRUM_TENSIONS, DRUM_BAND, 4, ("open_air",)),
    "drum_baffle_null": Case(DRUM_BAFFLED, DRUM_BAFFLED, DRUM_TENSIONS, DRUM_BAND, 4, ()),
}
# The enclosure (opt-in, named in candidates beside a rival mounting and the membrane's
# stiffness): a drum head (the direct FE engine) and G1 (disc held: the anchored engine,
# the anchor solved at each depth) over a hidden sealed cylinder, and their null sets.
ENCLOSURE_CANDIDATES = ("enclosure", "baffle", "uniform_stiffness")
ENCLOSURE_CASES = {
    "drum_enclosure_hidden": Case(DRUM, DRUM_ENCLOSED, DRUM_TENSIONS, DRUM_BAND, 4,
                                  ("enclosure",), candidates=ENCLOSURE_CANDIDATES),
    "drum_enclosure_null": Case(DRUM, DRUM, DRUM_TENSIONS, DRUM_BAND, 4, (),
                                candidates=ENCLOSURE_CANDIDATES),
    "g1_enclosure_hidden": Case(G1_OPEN, G1_ENCLOSED, fe_battery.AIR5, fe_battery.BAND, 2,
                                ("enclosure",), candidates=ENCLOSURE_CANDIDATES),
    "g1_enclosure_null": Case(G1_OPEN, G1_OPEN, fe_battery.AIR5, fe_battery.BAND, 2, (),
                              candidates=ENCLOSURE_CANDIDATES),
}
# The reproduction of issue 24: the head's tension unknown too (the data 10 % stiffer).
REPRODUCTION = Case(DRUM, DRUM_STIFFER_BAFFLED, DRUM_TENSIONS, DRUM_BAND, 4,
                    ("baffle", "uniform_stiffness"), ("uniform_stiffness",))


def condition_name(overrides: dict) -> str:
    if "membrane.prestretch" in overrides:
        return f"stretch{overrides['membrane.prestretch']:g}".replace(".", "p")
    return fe_battery.condition_name(overrides)


def truth_modes(case: Case, fe: FEModel | None = None) -> dict:
    fe = fe or FEModel(cache_dir=FE_CACHE)
    truth = parse_study(case.truth, name="truth")
    return {condition_name(o): fe.modes(truth.replace(o), f_max=BAND_MARGIN * case.band[1])
            for o in case.conditions}


def write_measured(case: Case, name: str, seed: int, folder: Path,
                   fe: FEModel | None = None) -> Path:
    """The case's measured set with the noise of ``fe_battery`` (seed) in ``folder``."""
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "base_study.yaml").write_text(yaml.safe_dump(dict(case.base), sort_keys=False))
    conditions = []
    log_band = (math.log(case.band[0]), math.log(case.band[1]))
    for cname, result in truth_modes(case, fe).items():
        rows = []
        for mode in result.modes:
            if fe_battery._order(mode.label) > case.orders or rng.random() < fe_battery.P_MISS:
                continue
            frequency = mode.frequency_hz * math.exp(rng.normal(0.0, fe_battery.SCATTER))
            if not case.band[0] <= frequency <= case.band[1]:
                continue
            rows.append((frequency,
                         fe_battery.written_label(mode.label) if rng.random() < 0.5 else ""))
        for _ in range(rng.poisson(fe_battery.SPURIOUS)):
            rows.append((math.exp(rng.uniform(*log_band)), ""))
        rows.sort()
        path = folder / f"{cname}_resonances.csv"
        path.write_text("freq_hz,label\n" + "".join(f"{f:.3f},{label}\n" for f, label in rows))
        overrides = next(o for o in case.conditions if condition_name(o) == cname)
        conditions.append({"name": cname, "set": dict(overrides), "resonances": path.name,
                           "band": [f"{case.band[0]:g} Hz", f"{case.band[1]:g} Hz"]})
    manifest = {"name": f"{name}_seed{seed}", "description": f"FE-made data ({name}), seed {seed}",
                "base_study": "base_study.yaml",
                "noise": {"frequency_relative": fe_battery.SCATTER,
                          "missing_probability": fe_battery.P_MISS,
                          "spurious_per_condition": fe_battery.SPURIOUS},
                **({"candidates": list(case.candidates)} if case.candidates else {}),
                "conditions": conditions}
    path = folder / "measured.yaml"
    path.write_text(yaml.safe_dump(manifest, sort_keys=False))
    return path


def right(case: Case, result) -> bool:
    """Exactly the hidden effects named (any order), or the hidden mounting in an ambiguous
    group with an allowed material effect -- never a material effect alone."""
    named = set(result.missing_effects)
    grouped = {e for g in result.ambiguous for e in g}
    if not case.missing:
        return not named and not result.ambiguous
    if named == set(case.missing) and not result.ambiguous:
        return True
    mounting = [e for e in case.missing if e in MOUNTINGS]
    others = set(case.missing) - set(mounting)
    return (bool(mounting) and set(mounting) <= named | grouped
            and not (named - set(case.missing))
            and grouped <= set(case.missing) | set(case.ambiguous_ok)
            and others <= named | grouped)


if __name__ == "__main__":       # fill the FE cache of every case (truth and base)
    from copdea_fem.progress import progress_to
    model = FEModel(cache_dir=FE_CACHE)
    with progress_to(print, only_info=True):          # the FE progress lines
        for case in [*CASES.values(), *REVERSE_CASES.values(), *ENCLOSURE_CASES.values(),
                     REPRODUCTION]:
            truth_modes(case, model)
            truth_modes(Case(case.base, case.base, case.conditions, case.band, case.orders,
                             ()), model)
    print(f"{model.solves} FE solves, {model.seconds:.0f} s")
