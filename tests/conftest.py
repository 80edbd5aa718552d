"""Shared fixtures: coarse studies and cached meshes."""

import os

# One BLAS thread: ARPACK's many small dense operations run far slower with
# threads competing on a 2-core machine (measured: up to 100x on small calls).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import pytest  # noqa: E402

from copdea_fem.study import parse_study  # noqa: E402

# A coarse mesh keeps the suite fast; the verification tests that need the
# default mesh say so explicitly.
COARSE = {"mesh": {"membrane_size": "6 mm", "order": 2}}


def coarse_study(**sections):
    raw = {key: dict(value) for key, value in COARSE.items()}
    for section, values in sections.items():
        raw.setdefault(section, {}).update(values)
    return parse_study(raw, name="test")


@pytest.fixture
def make_study():
    return coarse_study


@pytest.fixture
def figures(request):
    """``figures(title, lines)``: a slow test's measured figures, printed in the summary at
    the end of the run (they go into the CI log and the issue notes).  Carried as a report
    section, so they reach the summary from pytest-xdist's workers too."""
    def record(title, lines=()):
        text = "\n".join([title, *(f"  {line}" for line in lines)])
        request.node.add_report_section("call", "figures", text)
    return record


@pytest.fixture
def counted(monkeypatch):
    """``counted(module, "name")`` wraps ``module.name`` so that its calls are counted in
    ``counted.calls`` (a Counter by name) while the test runs: how often a file is read."""
    import collections

    calls = collections.Counter()

    def wrap(module, name):
        original = getattr(module, name)

        def counting(*args, **kwargs):
            calls[name] += 1
            return original(*args, **kwargs)
        monkeypatch.setattr(module, name, counting)
        return counting

    wrap.calls = calls
    return wrap


def pytest_terminal_summary(terminalreporter):
    texts = [content for outcome in ("passed", "failed")
             for report in terminalreporter.stats.get(outcome, [])
             for name, content in getattr(report, "sections", ())
             if name == "Captured figures call"]
    if texts:
        terminalreporter.section("measured figures")
        for text in texts:
            terminalreporter.write_line(text)
