"""The FE engine interface: both engines implement every method of ``Engine``, and
``copdea_fem.fe`` exports the public names without loading NGSolve (that nothing outside
``copdea_fem.fe`` imports an engine's folder is an import-linter contract:
tests/test_imports.py).

What an engine must provide is :class:`copdea_fem.fe.engines.Engine`; an engine that lacks
a method (or names its parameters otherwise) would fail only where that method is first
called, so the interface is checked here, on the classes, without solving anything.
"""

from __future__ import annotations

import inspect
import subprocess
import sys

import pytest

from copdea_fem import fe
from copdea_fem.fe.engines import Engine


def _members(cls) -> dict:
    """The public methods and attributes a class declares or inherits (not ``object``'s)."""
    return {name: value for name, value in inspect.getmembers(cls)
            if not name.startswith("_") and not hasattr(object, name)}


def _engines():
    from copdea_fem.fe.axisymmetric.engine import AxisymmetricEngine
    from copdea_fem.fe.quadrant.engine import QuadrantEngine
    return [QuadrantEngine, AxisymmetricEngine]


INTERFACE = {name: value for name, value in _members(Engine).items() if callable(value)}


def test_the_interface_names_what_the_package_asks_of_an_engine():
    assert {"prepare_mesh", "mesh_key", "space_key", "prestress_solver", "dry_modes",
            "coupled_modes", "threads", "estimate_size", "forced_problem", "driven_sector",
            "driven_parts",
            "electrode_forcing", "point_sampler", "prestressed_positions", "tracking_arrays",
            "output"} == set(INTERFACE)
    assert "name" in Engine.__annotations__


@pytest.mark.parametrize("engine", _engines(), ids=lambda cls: cls.__name__)
def test_each_engine_implements_every_method_with_the_interfaces_parameters(engine):
    for name, declared in INTERFACE.items():
        method = getattr(engine, name, None)
        assert callable(method), f"{engine.__name__} lacks {name}"
        wanted = list(inspect.signature(declared).parameters)
        assert list(inspect.signature(method).parameters) == wanted, (engine.__name__, name)
    assert isinstance(engine.name, str)


def test_the_engines_are_told_apart_by_their_names():
    names = [engine.name for engine in _engines()]
    assert sorted(names) == ["3d", "axisymmetric"]


def test_the_fe_package_exports_its_public_names_without_loading_ngsolve():
    code = ("import sys, copdea_fem.fe as fe; "
            "names = [fe.Engine, fe.engine_for, fe.check_size, fe.MAX_UNKNOWNS, "
            "fe.MESH_CACHE_VARIABLE]; "
            "print('ngsolve' in sys.modules, 'copdea_fem.fe.quadrant.engine' in sys.modules)")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=120)
    assert run.stdout.split() == ["False", "False"]
    for name in fe.__all__:
        assert getattr(fe, name) is not None, name
    with pytest.raises(AttributeError, match="no attribute 'engine_of'"):
        fe.engine_of  # noqa: B018
