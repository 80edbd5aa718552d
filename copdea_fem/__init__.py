"""copdea-fem: vibro-acoustic FE and reduced models of circular out-of-plane DEAs.

The pipeline: study (:mod:`copdea_fem.study`) -> mesh -> prestress -> linearised operators
-> eigen step -> labelled modes (:mod:`copdea_fem.fe`) -> files (:mod:`copdea_fem.output`);
the applications on top: the forced response (:mod:`copdea_fem.forced_response`), the
reduced ring model (:mod:`copdea_fem.reduced`), sweeps (:mod:`copdea_fem.sweeps`) and the
diagnosis (:mod:`copdea_fem.diagnosis`).

The Python API (:mod:`copdea_fem.api`) is available from the package; ``import copdea_fem``
stays light (NGSolve, pyvista and pandas load on first use)::

    import copdea_fem as cf
    sol = cf.solve(cf.load_study("studies/g1_z16_v2_quick.yaml"))
"""

__version__ = "0.1.0"

#: The names of :mod:`copdea_fem.api` exported here, imported on first access (PEP 562).
__all__ = ["load_study", "solve", "response", "force", "spectrum", "fit_material",
           "calibrate_damping", "sweep", "diagnose", "correlate", "identify", "synthesise",
           "Solution", "ResponseSolution", "ForceCurve", "Spectrum", "MaterialFitResult",
           "DampingCalibrationResult", "SweepResult", "Diagnosis", "CorrelateResult",
           "IdentifyResult", "SyntheticData", "SolveFailed", "StudyError", "OutputFolderError",
           "load_measured", "identify_file", "FileIdentifyResult", "excite", "statespace",
           "Excitation", "StateSpace"]


def __getattr__(name):
    if name in __all__:
        from copdea_fem import api
        return getattr(api, name)
    raise AttributeError(f"module 'copdea_fem' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
