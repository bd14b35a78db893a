"""The coupling schemes, and building one participant's from the configuration."""

from __future__ import annotations

from typing import TYPE_CHECKING

from gymprecice.plugin.precice_xml import PreciceConfig
from gymprecice.testing.fake_precice.config_extras import SchemeExtras
from gymprecice.testing.fake_precice.errors import PreciceError
from gymprecice.testing.fake_precice.schemes.base import Scheme
from gymprecice.testing.fake_precice.schemes.bi import BiScheme
from gymprecice.testing.fake_precice.schemes.composite import Composite
from gymprecice.testing.fake_precice.schemes.multi import MultiScheme

if TYPE_CHECKING:
    from gymprecice.testing.fake_precice.coupling import Coupling

__all__ = ["BiScheme", "Composite", "MultiScheme", "Scheme", "build_schemes"]


def build_schemes(
    owner: Coupling, cfg: PreciceConfig, name: str, extras: list[SchemeExtras]
) -> Composite:
    """The schemes that couple participant ``name``, checked the way preCICE's configuration is.

    ``extras`` holds, per ``<coupling-scheme:...>`` in document order, what
    :func:`~gymprecice.testing.fake_precice.config_extras.read_extras` read beside
    :mod:`gymprecice.precice_xml`.
    """
    schemes: list[Scheme] = []
    for spec, extra in zip(cfg.coupling_schemes, extras):
        if name not in spec.participants:
            continue
        if spec.time_window_method != "fixed" or not spec.time_window_size:
            raise PreciceError(
                f'gymprecice\'s fake_precice models <time-window-size value="..." /> with a '
                f'fixed size only, not method="{spec.time_window_method}" '
                f"(coupling scheme in line {spec.line})."
            )
        if spec.max_time is None and spec.max_time_windows is None:
            raise PreciceError(
                "At least one termination condition is required for the coupling scheme of "
                f'type "{spec.kind}". Please add a <max-time value="..."/> or '
                f'<max-time-windows value="..."/> tag inside your <coupling-scheme:'
                f"{spec.kind}> configuration."
            )
        kind = spec.kind
        scheme: Scheme
        if kind == "multi":
            scheme = MultiScheme(owner, spec, extra, name)
        elif kind in (
            "serial-explicit",
            "parallel-explicit",
            "serial-implicit",
            "parallel-implicit",
        ):
            scheme = BiScheme(owner, spec, extra, name)
        else:
            raise PreciceError(f'Unknown coupling scheme "coupling-scheme:{kind}".')
        if scheme.implicit and any(s.implicit for s in schemes):
            raise PreciceError(
                "You attempted to define a second implicit coupling-scheme for the "
                f'participant "{name}", which is not allowed. Please use a multi '
                "coupling-scheme for true implicit coupling of multiple participants."
            )
        for measure in scheme.measures:
            if (measure.data, measure.mesh) not in scheme.keys:
                raise PreciceError(
                    f'Data "{measure.data}" on mesh "{measure.mesh}" is not exchanged in '
                    "this coupling scheme, so it cannot have a convergence measure."
                )
        schemes.append(scheme)
    if not schemes:
        raise PreciceError(
            f'No coupling scheme defined for participant "{name}". Please make sure to '
            "provide at least one <coupling-scheme:TYPE> in your precice-config.xml that "
            "couples this participant using the <participants .../> tag."
        )
    return Composite(schemes)
