"""What the double reads of the preCICE XML beyond :mod:`gymprecice.precice_xml`."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from gymprecice.plugin.precice_xml import parse_tree
from gymprecice.testing.fake_precice.convergence import Measure


@dataclass
class SchemeExtras:
    """What ``precice_xml`` does not keep of a coupling scheme, read here once."""

    substeps: list[bool | None] = field(default_factory=list)  # per exchange, None: default
    measures: list[Measure] = field(default_factory=list)
    min_iterations: int = 1


def truthy(value: str | None) -> bool:
    return (value or "").strip().lower() in ("1", "yes", "true", "on")


def read_extras(path: Path) -> tuple[dict[str, str], bool, list[SchemeExtras]]:
    """Root attributes, whether logging is on, and per-scheme details, in document order."""
    root = parse_tree(path).getroot()
    log_enabled = True
    extras: list[SchemeExtras] = []
    for elem in root:
        if not isinstance(elem.tag, str):
            continue
        if elem.tag == "log":
            sinks = [s for s in elem if isinstance(s.tag, str) and s.tag == "sink"]
            switched_off = elem.get("enabled") is not None and not truthy(elem.get("enabled"))
            no_sink_on = bool(sinks) and not any(truthy(s.get("enabled", "1")) for s in sinks)
            log_enabled = log_enabled and not (switched_off or no_sink_on)
        elif elem.tag.startswith("coupling-scheme:"):
            extra = SchemeExtras()
            for child in elem:
                if not isinstance(child.tag, str):
                    continue
                tag = child.tag
                if tag == "exchange":
                    raw = child.get("substeps")
                    extra.substeps.append(None if raw is None else truthy(raw))
                elif tag == "min-iterations":
                    extra.min_iterations = int(float(child.get("value", "1")))
                elif tag.endswith("convergence-measure"):
                    kind = tag[: -len("-convergence-measure")]
                    extra.measures.append(
                        Measure(
                            kind=kind,
                            data=child.get("data", ""),
                            mesh=child.get("mesh", ""),
                            limit=float(child.get("limit", "0") or 0),
                            abs_limit=float(child.get("abs-limit", "0") or 0),
                            rel_limit=float(child.get("rel-limit", "0") or 0),
                            suffices=truthy(child.get("suffices")),
                            strict=truthy(child.get("strict")),
                        )
                    )
            extras.append(extra)
    return dict(root.attrib), log_enabled, extras
