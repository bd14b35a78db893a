"""Which preCICE the double says it is: the release it follows and its build information."""

from __future__ import annotations

#: The preCICE release whose behaviour the double follows.
PRECICE_VERSION = "3.4.1"
#: Version of these "bindings", like ``precice.__version__`` of pyprecice.
__version__ = "3.4.0+gymprecice.fake"
#: Lets code (and logs) tell the double from the real library.
IS_FAKE = True

VERSION_INFORMATION = (
    f"{PRECICE_VERSION};gymprecice fake_precice;PRECICE_FEATURE_MPI_COMMUNICATION=N;"
    "PRECICE_FEATURE_PETSC_MAPPING=N;PRECICE_FEATURE_GINKGO_MAPPING=N;"
    "PRECICE_FEATURE_PYTHON_ACTIONS=N;PRECICE_BINDINGS_C=N;PRECICE_BINDINGS_FORTRAN=N;"
    "CXX=none;CXXFLAGS=;LDFLAGS="
)


def get_version_information() -> bytes:
    """Like ``precice.get_version_information()``: preCICE's ``;``-separated build info, bytes."""
    return VERSION_INFORMATION.encode()
