"""The 3-D mesh symmetric under the diagonal mirror x <-> y (copdea_fem.fe.quadrant.mirrored).

The device (circle, square frame, sphere) is symmetric under (x, y) -> (y, x); its mesh must
be too, or the even-even sector's modes mix the square's classes A1 and B1 (issue 41).  The
check is the reflection itself, applied here to the mesh Netgen and the mirroring made:
every node lands on a node, every element on an element of the same region.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from copdea_fem.fe.quadrant.geometry import GeometrySpec, study_mesh
from copdea_fem.fe.symmetry import mirror_breaking
from copdea_fem.study import load_study

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "studies" / "g1_z16_v2_quick.yaml"
SWAP = np.array([[0.0, 1.0], [1.0, 0.0]])


def _image_nodes(points: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """The node each node's image lands on (asserted within 1e-12 of the mesh's extent)."""
    image = points.copy()
    image[:, :2] = points[:, :2] @ matrix.T
    distance, index = cKDTree(points).query(image)
    assert distance.max() <= 1e-12 * np.abs(points).max(), distance.max()
    return index


def _elements(mesh) -> dict:
    """(dimension, region name) -> set of sorted node tuples (0-based), volumes and faces."""
    ngmesh = mesh.ngmesh
    names = {3: [ngmesh.GetMaterial(k) for k in range(1, ngmesh.GetNDomains() + 1)],
             2: [fd.bcname for fd in ngmesh.FaceDescriptors()]}
    result: dict = {}
    for dimension, elements in ((3, ngmesh.Elements3D().NumPy()),
                                (2, ngmesh.Elements2D().NumPy())):
        for nodes, index in zip(elements["nodes"], elements["index"]):
            key = (dimension, names[dimension][index - 1])
            result.setdefault(key, set()).add(tuple(sorted(int(n) - 1 for n in nodes if n)))
    return result


@pytest.mark.parametrize("air", [True, False], ids=["quadrant-in-air", "plane-no-air"])
def test_the_mesh_maps_onto_itself_under_the_diagonal_mirror(air, tmp_path):
    """The bundled G1 quick study: the quadrant in air (square frame), and the whole plane
    without air (then also under x -> -x and y -> -y); regions kept, the quadrant's mirror
    planes swapped by x <-> y.  The mirrored elements are curved onto the true surfaces: the
    membrane's area is the annulus's to 3e-5 (uncurved, the rims' chords miss 2e-3)."""
    study = load_study(QUICK, {} if air else {"air.enabled": False})
    spec = GeometrySpec.from_study(study)
    assert spec.diagonal and spec.symmetry == ("quarter" if air else "none")
    mesh = study_mesh(study, cache_dir=tmp_path)
    points = mesh.ngmesh.Coordinates()
    elements = _elements(mesh)
    assert (3, "air_upper") in elements if air else (2, "membrane") in elements
    swap_names = {"mirror_x": "mirror_y", "mirror_y": "mirror_x"}
    mirrors = [(SWAP, swap_names)]
    if not air:
        mirrors += [(np.diag([-1.0, 1.0]), {}), (np.diag([1.0, -1.0]), {})]
    else:
        assert points[:, :2].min() >= 0.0                 # a quadrant
    for matrix, renamed in mirrors:
        image = _image_nodes(points, matrix)
        for (dimension, name), nodes in elements.items():
            mapped = {tuple(sorted(image[list(element)])) for element in nodes}
            assert mapped == elements[(dimension, renamed.get(name, name))], (name, matrix)
    import ngsolve
    area = ngsolve.Integrate(ngsolve.CoefficientFunction(1.0), mesh,
                             definedon=mesh.Boundaries("membrane"))
    annulus = math.pi * (spec.outer_radius**2 - spec.inner_radius**2) / (4 if air else 1)
    assert area == pytest.approx(annulus, rel=3e-5)    # measured 8e-6, 1.1e-5; straight: 2e-3
    # from the cache: the same nodes (Netgen writes 16 digits), still mirrored, curved onto
    # the same surfaces
    cached = study_mesh(study, cache_dir=tmp_path)
    np.testing.assert_allclose(cached.ngmesh.Coordinates(), points, rtol=0, atol=1e-15)
    _image_nodes(cached.ngmesh.Coordinates(), SWAP)
    assert ngsolve.Integrate(ngsolve.CoefficientFunction(1.0), cached,
                             definedon=cached.Boundaries("membrane")) == pytest.approx(area,
                                                                                      rel=1e-9)


@pytest.mark.parametrize("keys", [
    {"membrane": {"thickness_variation": [{"order": 2, "amplitude": 0.02, "angle": 0}]}},
    {"membrane": {"prestretch_anisotropy": 0.02}},
    {"imperfections": {"point_masses": [{"mass": 1e-4, "r": 0.025}]}},
], ids=["cos-2-theta", "anisotropy-along-x", "mass-off-centre"])
def test_an_imperfect_device_is_meshed_as_the_perfect_one(keys):
    """Imperfections, even those odd under x <-> y (cos 2 theta, a pre-stretch along x, a
    mass off the diagonal), are coefficients on the mesh: the imperfect device keeps the
    perfect one's octant-mirrored mesh (one cache key), so the two are compared on one mesh;
    with air a mass off the centre breaks the mirror planes and the whole device is meshed,
    still mirrored.  The scheme is in the cache key."""
    from copdea_fem.study import parse_study

    perfect = parse_study({"air": {"enabled": True}})
    study = parse_study({"air": {"enabled": True}, **keys})
    for air in (False, True):
        spec = GeometrySpec.from_study(study, with_air=air)
        assert spec.diagonal
        if air and mirror_breaking(study):
            assert spec.symmetry == "none"
        else:
            assert spec.key() == GeometrySpec.from_study(perfect, with_air=air).key()
        other = GeometrySpec(**{**spec.__dict__, "diagonal": False})
        assert other.key() != spec.key()
