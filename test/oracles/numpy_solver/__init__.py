"""The solver as numpy array code, frozen as the test oracle of the compiled path
(linkage_monitor.mechanics.kernels): every pose a stack of whole-array operations.
test/test_compiled_equals_reference.py holds the package's solver to it."""

from .solver import Solver

__all__ = ["Solver"]
