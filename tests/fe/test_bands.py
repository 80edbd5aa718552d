"""Complete bands and band-independent labels (issue 21).

A band must hold every mode a wider band holds inside it, with the same label: the
axisymmetric order loops may not stop at the first order with nothing in the band,
and a label may not depend on which modes the band happened to hold (the radial
order n counts from 0 Hz, the letters name the cos/sin member and the in-plane
family).  Coarse meshes: the comparisons are within one discretisation.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import COARSE_AIR, on_its_engine

from copdea_fem.fe.bands import OrderStop, coupled_start_modes, lowest_frequency_hz
from copdea_fem.fe.modes import IN_PLANE, OUT_OF_PLANE, PUMPING, Mode, assign_labels
from copdea_fem.fe.pipeline import coupled_modes, dry_modes
from copdea_fem.study import parse_study

pytest.importorskip("ngsolve")

G1_Z16 = {"geometry": {"frame": "baffle"}, "load": {"z": "16 mm", "voltage": "2 kV"}}
COARSE = {"membrane_size": "6 mm", "order": 2}


def study(engine="axisymmetric", air=False, mesh=COARSE, **eigen):
    raw = {**G1_Z16, "mesh": {**mesh, "engine": engine}, "air": {"enabled": air},
           "eigen": {"f_max": "1000 Hz", **eigen}}
    return parse_study(raw, name="bands")


def table(modes):
    return [(mode.label, mode.freq_hz) for mode in modes]


def inside(rows, f_min, f_max, margin=1e-6):
    """Rows clear of the band's edges (a mode on an edge may fall either side)."""
    return [(label, f) for label, f in rows
            if f_min * (1 + margin) <= f <= f_max * (1 - margin)]


def assert_same(narrow, wide, f_min, f_max):
    narrow, wide = inside(narrow, f_min, f_max), inside(wide, f_min, f_max)
    assert sorted(label for label, _ in narrow) == sorted(label for label, _ in wide), \
        (f_min, f_max, narrow, wide)
    by_label = dict(wide)
    for label, f in narrow:
        assert f == pytest.approx(by_label[label], rel=1e-7), (label, f_min, f_max)


@pytest.fixture(scope="module")
def dry_wide():
    return table(on_its_engine(dry_modes, study())[1])


def test_dry_wide_band_reaches_high_orders_and_names_the_in_plane_families(dry_wide):
    labels = {label for label, _ in dry_wide}
    assert {"(6,1)a", "(6,1)b", "ip(2,1)c", "ip(2,1)d", "ip(2,1)a", "ip(2,1)b"} <= labels
    assert len(labels) == len(dry_wide)            # unique labels


def test_narrow_dry_bands_hold_every_mode_of_the_wide_band(dry_wide):
    # the band first: nothing came back on main (the loop stopped at m = 0)
    bands = [(740.0, 780.0)]
    rng = np.random.default_rng(21)
    for _ in range(3):
        low = float(rng.uniform(350.0, 950.0))
        bands.append((low, low + float(rng.uniform(15.0, 50.0))))
    for f_min, f_max in bands:
        narrow = table(on_its_engine(dry_modes,
                                     study(f_min=f"{f_min} Hz", f_max=f"{f_max} Hz"))[1])
        assert narrow, (f_min, f_max)
        assert_same(narrow, dry_wide, f_min, f_max)


@pytest.mark.slow
def test_narrow_dry_band_has_the_same_labels_on_the_3d_engine():
    axisymmetric = table(on_its_engine(dry_modes, study(f_min="740 Hz", f_max="780 Hz"))[1])
    three_d = table(on_its_engine(dry_modes,
                                  study(engine="3d", f_min="740 Hz", f_max="780 Hz"))[1])
    assert sorted(label for label, _ in three_d) == sorted(label for label, _ in axisymmetric)
    by_label = dict(axisymmetric)
    for label, f in three_d:
        assert f == pytest.approx(by_label[label], rel=0.02), label


def test_coupled_band_labels_count_from_zero_hz():
    coarse_air = {**COARSE_AIR, "engine": "axisymmetric"}
    wide = on_its_engine(coupled_modes, study(air=True, mesh=coarse_air))
    # the band: main labelled (0,2), (1,2)a/b as (0,1), (1,1)a/b there
    narrow = on_its_engine(coupled_modes, study(air=True, mesh=coarse_air, f_min="900 Hz"))
    structural = [(m.label, m.freq_hz) for m in wide.modes if m.kind != "air"]
    assert {"(0,2)", "(1,2)a", "(9,1)a"} <= {label for label, _ in inside(structural, 900, 1000)}
    assert_same([(m.label, m.freq_hz) for m in narrow.modes if m.kind != "air"],
                structural, 900.0, 1000.0)
    # the dry partners of the narrow band: the wide band's, from f_min up
    assert_same(table(narrow.dry_modes), table(wide.dry_modes), 900.0, 1500.0)


# ------------------------------------------------------------------ the rules themselves
def test_order_stop_needs_the_lowest_modes_to_rise():
    stop = OrderStop(100.0)
    for lowest in (20.0, 150.0):          # order 1 above the top and above order 0: done
        stop.record(lowest)
    assert stop.done()
    stop = OrderStop(100.0)
    for lowest, done in ((150.0, False), (120.0, False), (90.0, False), (130.0, True)):
        stop.record(lowest)
        assert stop.done() is done, lowest


def test_lowest_frequency_dense_and_sparse_agree():
    import scipy.sparse as sp
    n = 600
    stiffness = sp.diags(np.linspace(1.0, 50.0, n) * (2 * np.pi * 10.0) ** 2).tocsr()
    mass = sp.identity(n, format="csr")
    assert lowest_frequency_hz(stiffness, mass) == pytest.approx(10.0, rel=1e-9)
    assert lowest_frequency_hz(stiffness[:300, :300], mass[:300, :300]) == \
        pytest.approx(10.0, rel=1e-9)
    assert coupled_start_modes([5.0, 50.0, 105.0, 120.0], 10.0, 100.0) == 4


def _mode(freq, kind, m, n, family, component="", sector=None):
    return Mode(index=0, freq_hz=freq, freq_im_hz=0.0, residual=0.0, kind=kind, m=m, n=n,
                label="", normal_fraction=1.0, disc_fraction=0.0, modal_mass=1.0,
                vector=np.zeros(1), family=family, in_plane_component=component,
                sector=sector)


def test_letters_name_the_member_not_its_rank():
    hoop_cos, hoop_sin = (_mode(600.0, IN_PLANE, 2, 1, f, "hoop") for f in ("cos", "sin"))
    radial_cos, radial_sin = (_mode(700.0, IN_PLANE, 2, 1, f, "radial") for f in ("cos", "sin"))
    sin_first = _mode(500.0, OUT_OF_PLANE, 1, 1, "sin")
    cos_second = _mode(500.0 + 1e-9, OUT_OF_PLANE, 1, 1, "cos")
    axisymmetric = _mode(400.0, OUT_OF_PLANE, 0, 1, "cos")
    modes = [hoop_cos, hoop_sin, radial_cos, radial_sin, sin_first, cos_second, axisymmetric]
    assign_labels(modes)
    assert [m.label for m in modes] == ["ip(2,1)a", "ip(2,1)b", "ip(2,1)c", "ip(2,1)d",
                                        "(1,1)b", "(1,1)a", "(0,1)"]
    assign_labels([radial_sin])            # alone in a band: the same name
    assert radial_sin.label == "ip(2,1)d"
    torsion, breathing = (_mode(f, IN_PLANE, 0, 1, "cos", c)
                          for f, c in ((600.0, "hoop"), (690.0, "radial")))
    assign_labels([breathing])
    assert breathing.label == "ip(0,1)b"
    assign_labels([torsion, breathing])
    assert (torsion.label, breathing.label) == ("ip(0,1)a", "ip(0,1)b")
    # a family the rule cannot tell apart keeps unique labels
    twins = [_mode(f, OUT_OF_PLANE, 1, 1, "cos") for f in (500.0, 510.0)]
    assign_labels(twins + [_mode(300.0, PUMPING, 0, 1, "cos")])
    assert [m.label for m in twins] == ["(1,1)a", "(1,1)a-2"]
