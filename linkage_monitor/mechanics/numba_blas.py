"""The BLAS and LAPACK the compiled kernels call (numba's ``@`` and its linear algebra), found without
importing ``scipy.linalg`` whole.

numba takes BLAS and LAPACK from scipy's two Cython modules ``scipy.linalg.cython_blas`` and
``scipy.linalg.cython_lapack`` (their exported C functions): it imports the first when the first
kernel is loaded (``numba.np.arraymath`` checks that a BLAS is there), and its C helpers import them
again by name when a kernel first calls one. Importing ``scipy.linalg.cython_blas`` runs
``scipy.linalg/__init__.py`` first: scipy's whole linear algebra API, with numpy.testing and pydoc
(~0.12 s of a replay's start), none of which a kernel uses. ``load_alone`` loads the two extension
modules by themselves under their own names, so numba finds them imported; a later
``import scipy.linalg`` (the calibration's least squares) runs the package as usual and takes these two
as they are. Where scipy is not laid out so (the modules not found beside its package, or not
loading alone), numba imports them its own way.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import sys

MODULES = ("scipy.linalg.cython_blas", "scipy.linalg.cython_lapack")


def load_alone() -> None:
    """Import ``MODULES`` without their package ``scipy.linalg`` (module docstring), unless it is imported."""
    if "scipy.linalg" in sys.modules:
        return
    scipy = importlib.util.find_spec("scipy")
    if scipy is None or not scipy.submodule_search_locations:
        return
    locations = [f"{location}/linalg" for location in scipy.submodule_search_locations]
    for name in MODULES:
        if name in sys.modules:
            continue
        spec = importlib.machinery.PathFinder.find_spec(name, locations)
        if spec is None or spec.loader is None:
            return
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        try:
            spec.loader.exec_module(module)
        except ImportError:   # numba imports it its own way (and says what is wrong)
            del sys.modules[name]
            return
