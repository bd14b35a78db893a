"""Griffe extension for the documentation site: the docstrings' reST markup, as Markdown.

The docstrings cross-reference with Sphinx roles (:class:`EnvPool`,
:func:`gymprecice.rllib.register_env`), which Markdown shows verbatim. Each role becomes
an optional cross-reference of mkdocs-autorefs: a link where the site renders the object,
plain code where it does not (a standard-library or Gymnasium object, a private helper).
Markdown references written as ``[name][gymprecice.x]`` stay strict and fail the build
when they do not resolve. A reST literal-block marker (``text::``) becomes one colon.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

#: reST's literal-block marker: "text::" (a colon stays) or a lone "::" (dropped); the
#: indented block after it is already a code block in Markdown
_LITERAL = re.compile(r"(?:(?<=\S):|\s*)::(?=[ \t]*\n[ \t]*\n)")
_ROLE = re.compile(r":(?:py:)?(?:mod|class|func|meth|data|attr|exc|obj):`~?([^`<>]+?)`")


def _resolve(name: str, obj: griffe.Object) -> str:
    """A dotted path for a role's target; a bare or relative name is looked up from obj."""
    target = name.lstrip(".")
    if "." in target and target.split(".", 1)[0] in (
        "gymprecice",
        "gymprecice_openfoam",
        "gymprecice_dealii",
        "gymprecice_fenics",
        "gymprecice_lab",
        "gymprecice_tutorials",
    ):
        return target
    scope = obj if obj.is_module or obj.is_class else obj.parent
    while scope is not None:
        head = target.split(".", 1)[0]
        if head in scope.members:
            return f"{scope.path}.{target}"
        scope = scope.parent
    return target


class SphinxRoles(griffe.Extension):
    """Rewrite ``:role:`target``` into an optional autoref and ``text::`` into ``text:``."""

    def on_object(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        docstring = obj.docstring
        if docstring is None or ":" not in docstring.value:
            return

        def link(match: re.Match[str]) -> str:
            shown = (
                match.group(1).rsplit(".", 1)[-1] if match.group(0).count("~") else match.group(1)
            )
            return (
                f'<autoref identifier="{_resolve(match.group(1), obj)}" optional>'
                f"<code>{shown}</code></autoref>"
            )

        docstring.value = _LITERAL.sub(":", _ROLE.sub(link, docstring.value))
