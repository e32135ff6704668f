"""Errors of the mechanics package; every one is a ``ValueError`` naming the input at fault."""

from __future__ import annotations


class LinkageError(ValueError):
    """Base class: something about the mechanism or its inputs prevents a solution."""


class MechanismFileError(LinkageError):
    """A mechanism description (YAML file or dict) is malformed or inconsistent.

    ``str(err)`` reads ``"<file>: <key path>: <what is wrong>"``, e.g.
    ``"belarus.yaml: hinges[3].bodies: body 'lower_lnk' is not defined (bodies: frame, ...)"``.
    """

    def __init__(self, file: str, key: str, reason: str) -> None:
        self.file = file
        self.key = key
        self.reason = reason
        super().__init__(f"{file}: {key}: {reason}" if key else f"{file}: {reason}")


class InputError(LinkageError):
    """A solver input is unusable: NaN/inf, unknown or missing name, negative absolute pressure."""


class AssemblyError(LinkageError):
    """The linkage cannot be assembled for the given inputs; the message says by how much."""


class DeadCentreError(LinkageError):
    """Near-singular kinematics or statics (dead centre); the message gives the condition number."""


class UnobservableError(LinkageError):
    """Too few measurements: names the free degrees of freedom or the undetermined unknowns."""
