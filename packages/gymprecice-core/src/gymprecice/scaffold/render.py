"""How ``gymprecice new`` turns its templates into text: ``{{name}}`` placeholders
filled, values written as Python and JSON source the way ``ruff format`` and the docs
write them, and long docstring and Markdown paragraphs filled again to :data:`WIDTH`, so
a new package starts clean under the user's own linters.
"""

from __future__ import annotations

import re
import textwrap
from typing import Any

__all__ = ["WIDTH", "literal", "render", "to_json", "wrap_docstrings", "wrap_markdown"]

_PLACEHOLDER = re.compile(r"\{\{(\w+)\}\}")
#: the line width the written Python files keep (ruff's and black's default)
WIDTH = 88


def render(text: str, values: dict[str, Any]) -> str:
    """``text`` with every ``{{name}}`` replaced by ``values[name]``; a name without a
    value is a :class:`KeyError` (a template bug, never silently left in a file)."""

    def one(match: re.Match[str]) -> str:
        return str(values[match.group(1)])

    return _PLACEHOLDER.sub(one, text)


def literal(value: Any, indent: int = 0, room: int = WIDTH) -> str:
    """``value`` as Python source, as ``ruff format`` writes it: on one line where it fits
    in ``room`` characters, else one item per line with a trailing comma."""
    flat = _flat(value)
    if len(flat) <= room or not isinstance(value, (list, tuple, dict)) or not value:
        return flat
    pad = " " * (indent + 4)
    if isinstance(value, dict):
        items = [
            f"{pad}{_flat(k)}: {literal(v, indent + 4, WIDTH - indent - 6 - len(_flat(k)))},"
            for k, v in value.items()
        ]
        open_, close = "{", "}"
    else:
        items = [f"{pad}{literal(v, indent + 4, WIDTH - indent - 5)}," for v in value]
        open_, close = ("[", "]") if isinstance(value, list) else ("(", ")")
    return "\n".join([open_, *items, " " * indent + close])


def _flat(value: Any) -> str:
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_flat(k)}: {_flat(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(_flat(v) for v in value) + "]"
    if isinstance(value, tuple):
        inner = ", ".join(_flat(v) for v in value)
        return f"({inner},)" if len(value) == 1 else f"({inner})"
    return repr(value)


def to_json(value: Any, indent: int = 0) -> str:
    """``value`` as JSON, small objects and lists on one line (as the docs write them)."""
    import json

    flat = json.dumps(value)
    if len(flat) + indent <= WIDTH or not isinstance(value, (dict, list)) or not value:
        return flat
    pad = " " * (indent + 2)
    if isinstance(value, dict):
        items = [f"{pad}{json.dumps(k)}: {to_json(v, indent + 2)}" for k, v in value.items()]
        return "{\n" + ",\n".join(items) + "\n" + " " * indent + "}"
    return (
        "[\n"
        + ",\n".join(f"{pad}{to_json(v, indent + 2)}" for v in value)
        + "\n"
        + " " * indent
        + "]"
    )


def _fill(paragraph: list[str]) -> list[str]:
    """``paragraph`` filled to :data:`WIDTH` where a line is longer, keeping the first
    line's indentation and a bullet's hanging indent."""
    if not paragraph or max(map(len, paragraph)) <= WIDTH:
        return list(paragraph)
    first = paragraph[0]
    indent = first[: len(first) - len(first.lstrip())]
    hanging = indent + ("  " if first.lstrip().startswith("* ") else "")
    return textwrap.wrap(
        " ".join(line.strip() for line in paragraph),
        WIDTH,
        initial_indent=indent,
        subsequent_indent=hanging,
        break_long_words=False,
        break_on_hyphens=False,
    )


def wrap_markdown(text: str) -> str:
    """Markdown whose paragraphs and list items holding a long line are filled again;
    headings and code blocks are left as they are."""
    out: list[str] = []
    paragraph: list[str] = []
    fenced = False
    for line in text.splitlines():
        stripped = line.strip()
        if fenced or not stripped or stripped.startswith(("#", "```")):
            out += _fill(paragraph)
            paragraph = []
            fenced ^= stripped.startswith("```")
            out.append(line)
            continue
        if stripped.startswith("* "):
            out += _fill(paragraph)
            paragraph = []
        paragraph.append(line)
    out += _fill(paragraph)
    return "\n".join(out) + ("\n" if text.endswith("\n") else "")


def wrap_docstrings(source: str) -> str:
    """Python source whose docstring paragraphs holding a line longer than :data:`WIDTH`
    are filled again (a text filled into a docstring is one line), keeping their
    indentation and a bullet's hanging indent."""
    out: list[str] = []
    paragraph: list[str] = []
    inside = False

    def flush() -> None:
        out.extend(_fill(paragraph))
        paragraph.clear()

    for line in source.splitlines():
        quotes = line.count('"""') % 2 == 1
        text = line.strip()
        if inside or text.startswith('"""'):
            ends = (inside and quotes) or (not inside and not quotes and text.endswith('"""'))
            if not text or text.startswith("* ") or set(text) <= set('-"'):
                flush()
            if text and not set(text) <= set('-"'):
                paragraph.append(line)
            else:
                out.append(line)
            if ends or (not inside and text == '"""'):
                flush()
        else:
            flush()
            out.append(line)
        if quotes:
            inside = not inside
    flush()
    return "\n".join(out) + ("\n" if source.endswith("\n") else "")
