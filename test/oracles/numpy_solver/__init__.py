"""The solver as numpy array code, the test oracle of the compiled path
(linkage_monitor.mechanics.kernels): every pose a stack of whole-array operations, its own
equations of the kinematics and the statics and its own linear algebra; what is not physics — the
input checks, the index structures (``KinematicLayout``, ``StaticsLayout``, ``ResultLayout``), the
verdicts' wording and the result types — is the package's, imported.
test/test_compiled_equals_reference.py holds the package's solver to it."""

from .solver import Solver

__all__ = ["Solver"]
