"""Shared helpers of the reduced-model tests (paper data: Table 1).

A plain module with a unique name (not conftest.py), imported by the tests.
"""

from pathlib import Path

from copdea_fem.fe.materials import Membrane
from copdea_fem.reduced.rings import RingModel
from copdea_fem.study import parse_study

DATA = Path(__file__).parent / "data"
G1_INNER, G2_INNER = 0.017, 0.012          # m, Table 1
G1_DISC, G2_DISC = 3.0e-3, 1.9e-3          # kg, Table 1
OUTER = 0.0355                             # m, Table 1


def paper_study(inner=G1_INNER, disc=G1_DISC, z=0.016, voltage=2000.0, motion="spring", **more):
    """A study at one of the paper's operating points (defaults: G1, z = 16 mm, 2 kV)."""
    raw = {"geometry": {"inner_radius": inner}, "disc": {"mass": disc, "motion": motion},
           "load": {"z": z, "voltage": voltage}, "output": {"plots": False}}
    for dotted, value in more.items():
        section, key = dotted.split("__")
        raw.setdefault(section, {})[key] = value
    return parse_study(raw, name="test")


def ring_model(rings=6, inner=G1_INNER, disc=G1_DISC, disc_free=True, spring=52.0):
    membrane = Membrane.from_study(parse_study({}))
    return RingModel(membrane, OUTER, inner, rings, disc, disc_free, spring)

