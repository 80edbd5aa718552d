"""Cache keys hold a fingerprint of the code that made the entry (issue 21)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from copdea_fem import fingerprint
from copdea_fem.study import parse_study

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture
def fresh_fingerprints():
    fingerprint.code_fingerprint.cache_clear()
    yield
    fingerprint.code_fingerprint.cache_clear()


def test_the_fingerprint_follows_its_sources_only(tmp_path, monkeypatch, fresh_fingerprints):
    (tmp_path / "solver").mkdir()
    (tmp_path / "physics.py").write_text("K = 1.0\n")
    (tmp_path / "solver" / "band.py").write_text("TOL = 1e-6\n")
    (tmp_path / "cli.py").write_text("print('hello')\n")
    monkeypatch.setattr(fingerprint, "PACKAGE", tmp_path)
    sources = ("physics.py", "solver")

    def current():
        fingerprint.code_fingerprint.cache_clear()
        return fingerprint.code_fingerprint(sources)

    first = current()
    (tmp_path / "cli.py").write_text("print('bye')\n")            # not a source: same key
    assert current() == first
    (tmp_path / "solver" / "band.py").write_text("TOL = 1e-8\n")  # a file below a folder
    changed = current()
    assert changed != first
    (tmp_path / "solver" / "band.py").write_bytes(b"TOL = 1e-8\r\n")   # line endings only
    assert current() == changed
    with pytest.raises(FileNotFoundError, match="gone.py"):
        fingerprint.code_fingerprint(("gone.py",))


def test_every_named_source_exists(fresh_fingerprints):
    for sources in (fingerprint.MESH_SOURCES, fingerprint.FE_SOURCES,
                    fingerprint.REDUCED_SOURCES):
        assert len(fingerprint.code_fingerprint(sources)) == 16


def test_mesh_fe_and_sweep_keys_change_with_the_code(monkeypatch):
    from copdea_fem.diagnosis import fe
    from copdea_fem.fe.quadrant import geometry
    from copdea_fem.sweeps import grid, parse_sweep

    study = parse_study({"geometry": {"frame": "baffle"}}, name="keys")
    spec = geometry.GeometrySpec.from_study(study)
    sweep_raw = {"study": "g1_z16_v2.yaml", "model": "dry",
                 "set": {"air.enabled": False}, "axes": {"load.voltage": ["1 kV", "2 kV"]}}

    def keys():
        sweep = parse_sweep(sweep_raw, base_dir=ROOT / "studies")
        return spec.key(), fe.fe_key(fe.fe_study(study)), sweep.points[0].study_hash

    before = keys()
    monkeypatch.setattr(geometry, "mesh_fingerprint", lambda: "other mesh code")
    monkeypatch.setattr(fe, "fe_fingerprint", lambda: "other FE code")
    monkeypatch.setattr(grid, "model_fingerprint", lambda model: "other FE code")
    after = keys()
    assert all(a != b for a, b in zip(before, after)), (before, after)


def test_a_stale_committed_fe_cache_is_named_with_its_refill_command(tmp_path):
    sys.path.insert(0, str(ROOT / "tests" / "diagnosis"))
    try:
        import fe_battery
    finally:
        sys.path.pop(0)
    missing = fe_battery.missing_entries(tmp_path)          # an empty folder: all missing
    assert missing and set(missing) == fe_battery.battery_keys()
    message = fe_battery.stale_message(missing)
    assert "python tests/diagnosis/fe_battery.py --refill" in message
    assert fe_battery.REFILL_VARIABLE in message


def test_the_fe_fingerprint_holds_every_fe_module_that_computes_modes(tmp_path, monkeypatch,
                                                                      fresh_fingerprints):
    """FE_SOURCES is the folder copdea_fem/fe less what computes no modes (the orchestration,
    the forced response, the ParaView fields): a new FE file is in without editing a list."""
    package = ROOT / "copdea_fem"
    modules = {path.relative_to(package).as_posix() for path in (package / "fe").rglob("*.py")}
    fe_sources = set(fingerprint.FE_SOURCES)
    assert fe_sources <= modules
    left_out = modules - fe_sources
    assert all(any(name == out or name.startswith(out + "/")
                   for out in fingerprint.NOT_FE_SOURCES) for name in left_out)
    assert {"fe/axisymmetric/engine.py", "fe/quadrant/engine.py", "fe/eigen/band.py",
            "fe/prestress.py", "fe/modes.py"} <= fe_sources
    assert {"fe/pipeline.py", "fe/forced/harmonic.py", "fe/quadrant/fields.py",
            "fe/axisymmetric/forced.py"} <= left_out
    # a new module of the FE core is covered at once
    copy = tmp_path / "copdea_fem"
    (copy / "fe" / "new").mkdir(parents=True)
    (copy / "fe" / "new" / "physics.py").write_text("K = 1.0\n")
    monkeypatch.setattr(fingerprint, "PACKAGE", copy)
    assert "fe/new/physics.py" in fingerprint._modules_of("fe", fingerprint.NOT_FE_SOURCES)


def test_docstrings_and_comments_keep_the_fingerprint(tmp_path, monkeypatch, fresh_fingerprints):
    """The fingerprint hashes the code, not its prose: a docstring or a comment edit keeps
    the caches warm, any code edit (a constant, an annotation) does not."""
    (tmp_path / "physics.py").write_text('"""Doc."""\nK = 1.0  # N/m\n"""Stiffness."""\n\n\n'
                                         'def f(x):\n    """Doc."""\n    return K * x\n')
    monkeypatch.setattr(fingerprint, "PACKAGE", tmp_path)

    def current():
        fingerprint.code_fingerprint.cache_clear()
        return fingerprint.code_fingerprint(("physics.py",))

    first = current()
    (tmp_path / "physics.py").write_text('"""Other words."""\nK = 1.0  # another comment\n'
                                         '"""Spring stiffness [N/m]."""\n\n\n'
                                         'def f(x):\n    """More."""\n    return K * x\n')
    assert current() == first
    (tmp_path / "physics.py").write_text('"""Doc."""\nK = 2.0\n\n\ndef f(x):\n'
                                         '    return K * x\n')
    assert current() != first
