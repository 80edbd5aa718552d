"""Result files: modes.csv / modes.json, ParaView .pvd/.vtu, PNG plots.

Every writer takes a target directory: the staging folder of
:func:`copdea_fem.folders.result_directory`, renamed into place only when
everything is written, so a failed run leaves no half-finished results behind.

- :mod:`~copdea_fem.output.tables`: modes.csv/json, the force table;
- :mod:`~copdea_fem.output.results`: the files of ``solve`` and ``force``;
- :mod:`~copdea_fem.output.plots`: PNG figures (matplotlib; imported only when
  ``output.plots`` is on).

The fields themselves are the engine's: :meth:`copdea_fem.fe.engines.Engine.output` samples
the prestress, the modes and the air into the meshes of :mod:`copdea_fem.vtu` (the API's
:class:`copdea_fem.api.Solution` asks it); the writers here are the same for every engine.
"""
