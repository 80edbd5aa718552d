"""Exceptions of the band eigensolver; each message names the argument and what is allowed."""

from __future__ import annotations


class EigenInputError(ValueError):
    """An argument of the eigensolver is outside what is allowed; the message says which."""


class TooManyModesError(EigenInputError):
    """The band holds more eigenpairs than ``max_modes``."""


class BackendUnavailableError(RuntimeError):
    """The requested factorisation back-end is not installed; the message says how to get it."""


class EigenSolverError(RuntimeError):
    """The Krylov run or the factorisation failed, or the band could not be covered."""


class EigenResidualError(RuntimeError):
    """An eigenpair's relative residual is above ``residual_tol``."""
