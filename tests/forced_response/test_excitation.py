"""The criterion of ``excite`` (copdea_fem.forced_response.excitation) and the C4v symmetry
of the drive the 3-D quadrant sees, checked against closed forms.

- **The inseparable report**: sin alpha of a row against rows at known angles, and the
  cost it stands for (module notes, eq. 3) against the least-norm drive that NumPy's
  pseudo-inverse gives for the two constraints.
- **The folding of segments onto the quadrant's sectors** (eq. 2 of
  :mod:`copdea_fem.fe.forced.electrode`): eight 45-degree sectors driven by the order-2
  pattern fold onto the even-even sector as a weight odd under the diagonal reflection
  x <-> y (the class B1 of the square's C4v group), so that a mode even under it (A1: the
  orders 0, 4, 8, ... of the square frame) is not driven at all by symmetry.
- **The modes of the quadrant** (slow): the order-2 pattern's modal forces on the A1 modes
  of the even-even sector against its B1 modes', the modes' classes read from their
  sampled shapes (not from their labels).
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "studies" / "g1_z16_v2_quick.yaml"
EIGHT_SECTORS = ("electrodes.segments=[" + ", ".join(
    f"{{name: s{k}, theta: [{45 * k}, {45 * (k + 1)}]}}" for k in range(8)) + "]")
#: The order-2 pattern of eight 45-degree sectors: the sign of cos 2 theta at each sector
#: (its Fourier factors s_2 cancel: a pure cos 2 theta drive, B1 of the square).
ORDER_TWO = np.array([1, -1, -1, 1, 1, -1, -1, 1], float)


def test_the_sine_from_the_targets_is_the_angle_between_the_rows():
    from copdea_fem.forced_response.excitation import sine_from_targets

    rng = np.random.default_rng(3)
    basis, _ = np.linalg.qr(rng.normal(size=(5, 5)) + 1j * rng.normal(size=(5, 5)))
    target = 2.0 * basis[:, 0] * np.exp(0.7j)
    for angle in (0.0, 0.05, 0.3, np.pi / 2):
        row = 3.0 * np.exp(-1.1j) * (np.cos(angle) * basis[:, 0] + np.sin(angle) * basis[:, 1])
        assert sine_from_targets(row, target[None, :]) == pytest.approx(np.sin(angle),
                                                                        abs=1e-12)
    # a row in the span of two targets is parallel to them
    both = np.stack([basis[:, 0], basis[:, 1]])
    assert sine_from_targets(basis[:, 0] - 2j * basis[:, 1], both) <= 1e-12
    assert sine_from_targets(np.zeros(5), target[None, :]) == np.inf


def test_holding_a_mode_down_costs_the_target_the_sine_of_its_angle():
    """The least drive with ``t u = 1`` and ``g u = 0`` (pseudo-inverse) is ``1 / sin alpha``
    times the least one with ``t u = 1`` alone (notes, eq. 3): at a peak drive the target's
    response falls by sin alpha."""
    from copdea_fem.forced_response.excitation import PARALLEL_SINE, sine_from_targets

    rng = np.random.default_rng(7)
    target = rng.normal(size=8) + 1j * rng.normal(size=8)
    for scale in (1e-3, 5e-2, 0.4):
        row = target * (1 + 0.2j) + scale * (rng.normal(size=8) + 1j * rng.normal(size=8))
        alone = np.linalg.norm(np.linalg.pinv(target[None, :]) @ [1.0])
        held = np.linalg.norm(np.linalg.pinv(np.stack([target, row])) @ [1.0, 0.0])
        assert alone / held == pytest.approx(sine_from_targets(row, target[None, :]),
                                             rel=1e-9)
    assert PARALLEL_SINE == pytest.approx(0.1)             # -20 dB


class _Model:
    """A modal model of one channel whose rows of G are given (denominators 1)."""

    def __init__(self, rows, labels):
        rows = np.asarray(rows, complex)
        self.inputs = [f"s{k}" for k in range(rows.shape[1])]
        self.labels = labels
        self.channels = [SimpleNamespace(participation=rows,
                                         denominators=lambda omega: np.ones((1, len(rows))))]

    def structural_modes(self, f_max, out_of_plane=False):
        return [(0, j, label, 100.0 * (j + 1)) for j, label in enumerate(self.labels)]


def test_a_nearly_parallel_row_is_reported_and_not_traded_against():
    """The 3-D figure's case with two inputs: a large mode 0.05 rad off the target's row
    (reported) and a small one 0.3 rad off (not reported).  Two inputs can hold one mode at
    zero under a unit target response: the separable one, exactly, since the parallel one
    is not in O (traded against, it would keep the separable one up by about 20 dB)."""
    from copdea_fem.forced_response.excitation import design_drive

    target = np.array([1.0, 0.0])
    near = 5.0 * np.array([np.cos(0.05), np.sin(0.05)])
    far = 0.5 * np.array([np.cos(0.3), np.sin(0.3)]) * np.exp(0.4j)
    model = _Model([target, near, far, np.zeros(2)], ["(2,1)a", "(6,1)a", "(0,1)", "(4,1)a"])
    design = design_drive(model, ["(2,1)"], 100.0, 1e9)
    reported = [line.split(":")[0] for line in design.inseparable]
    assert reported == ["(6,1)a"]
    assert "0.05 rad" in design.inseparable[0]
    levels = dict(zip(design.labels, design.level_db))
    # held at zero but for the regularisation of (2): epsilon / |far|^2 ~ 5e-8 (-146 dB)
    assert levels["(0,1)"] <= -120.0
    # the parallel mode then goes with the target: |near . u| / |t . u| in closed form,
    # u = (1, -cot 0.3) up to scale
    drive = np.array([1.0, -1.0 / np.tan(0.3)])
    assert levels["(6,1)a"] == pytest.approx(20 * np.log10(abs(near @ drive)),
                                             abs=1e-5)      # epsilon again: 5e-8 -> 4e-7 dB
    assert levels["(4,1)a"] == -np.inf


def test_the_order_two_pattern_folds_onto_the_quadrant_as_a_b1_weight():
    """W_ee(y, x) = -W_ee(x, y) at points off the sectors' edges (eq. 2 of the electrode
    module, NumPy), and the other three sectors receive nothing of it that is even in the
    diagonal: the folding itself cannot drive an A1 mode."""
    from copdea_fem.fe.forced.electrode import SegmentWeight
    from copdea_fem.fe.symmetry import SECTORS

    weights = [SegmentWeight.from_degrees((45 * k, 45 * (k + 1))) for k in range(8)]
    rng = np.random.default_rng(5)
    radius = rng.uniform(0.017, 0.0355, 200)
    theta = rng.uniform(0.01, np.pi / 2 - 0.01, 200)
    theta = theta[np.abs(theta - np.pi / 4) > 0.01]
    radius = radius[:theta.size]
    x, y = radius * np.cos(theta), radius * np.sin(theta)

    def folded(sector, px, py):
        return sum(d * w.sector_weight(sector, px, py) for d, w in zip(ORDER_TWO, weights))

    even_even = SECTORS[0]
    assert np.allclose(np.abs(folded(even_even, x, y)), 1.0)           # +-1 on each half
    assert np.array_equal(folded(even_even, y, x), -folded(even_even, x, y))
    for sector in SECTORS[1:]:
        assert np.allclose(folded(sector, x, y), 0.0)     # cos 2 theta: even-even only


def _diagonal_class(positions_xy, sampler, mode, count):
    """(A1 part, B1 part) of a mode's sampled u_z: its even and odd parts under x <-> y."""
    shape = sampler.displacement(mode)[:, 2]
    here, mirrored = shape[:count], shape[count:]
    even = np.linalg.norm(here + mirrored) / 2
    odd = np.linalg.norm(here - mirrored) / 2
    return even / (even + odd), odd / (even + odd)


@pytest.mark.slow
def test_the_order_two_pattern_drives_no_a1_mode_of_the_quadrant():
    """The square frame's C4v: the order-2 pattern (B1) drives no mode of the even-even
    sector that is even under x <-> y (A1), to 1e-6 of the B1 modes' modal forces.  It
    holds because the quadrant's mesh is one octant mirrored (copdea_fem.fe.quadrant.
    mirrored); Netgen's own quadrant mesh mixed the classes (0.6 % of the (0,1)'s u_z, 6.5 %
    of the (0,2)'s) and the pattern drove the (0,2) at 0.29 of the (6,1)a's modal force."""
    from copdea_fem.api import load_study
    from copdea_fem.fe import engine_for, run_solve
    from copdea_fem.forced_response.modal_inputs import ModalInputs, drive_inputs, study_points

    study = load_study(QUICK, [EIGHT_SECTORS])
    solution = run_solve(study, engine=engine_for(study))
    names, positions = study_points(solution, study)
    model = ModalInputs.build(solution, study, drive_inputs(study), positions, names)
    state, engine = solution.state, solution.engine
    radius = np.linspace(state.inner_radius, state.outer_radius, 9)[1:-1]
    theta = np.radians(np.linspace(2.0, 43.0, 12))
    grid_r, grid_theta = np.meshgrid(radius, theta, indexing="ij")
    here = np.column_stack([(grid_r * np.cos(grid_theta)).ravel(),
                            (grid_r * np.sin(grid_theta)).ravel()])
    sampler = engine.point_sampler(state, engine.prestressed_positions(
        state, np.vstack([here, here[:, ::-1]]), study.load.z))
    channel = next(c for c in model.channels if c.name.startswith("even-even"))
    modes = {mode.label: mode for mode in solution.modes
             if mode.sector is not None and mode.sector.name == "even-even"}
    a1, b1 = [], []
    for j, label in enumerate(channel.labels):
        if not channel.out_of_plane[j]:
            continue
        even, odd = _diagonal_class(here, sampler, modes[label], len(here))
        force = abs(channel.participation[j] @ ORDER_TWO)
        (a1 if even > odd else b1).append((label, force))
    assert a1 and b1
    largest = max(force for _, force in b1)
    assert max(force for _, force in a1) <= 1e-6 * largest, (a1, b1)
