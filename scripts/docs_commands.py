"""The command reference page, written from the ``gymprecice`` command line's own parsers.

:func:`command_reference` builds the parser ``gymprecice`` itself runs
(:func:`gymprecice.cli.build_parser`: core's commands, then every installed plugin's) and
writes one section per command: what it does, its usage, each argument with its default
and help, and an example. ``docs/reference/commands.md`` calls it through the docs macros
(scripts/docs_macros.py) when the site is built, so the page says what ``--help`` says.

The examples are the only text written here by hand, and each is parsed with the same
parser while the page is built: an example that no longer parses (a renamed option, a
removed command) fails the build, naming it. A command without an example here gets one
made of its required arguments.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import html
import importlib.metadata
import io
import re
import shlex
from pathlib import Path

__all__ = ["EXAMPLES", "ExampleError", "command_reference", "commands"]

#: one example per command, as a user types it
EXAMPLES: dict[str, str] = {
    "plugins": "gymprecice plugins --hook gymprecice_launch_solver",
    "check": "gymprecice check path/to/case",
    "doctor": "gymprecice doctor --json",
    "install": "gymprecice install",
    "sketch": "gymprecice sketch jet-cylinder --out jet-cylinder.png",
    "clean": "gymprecice clean --dry-run",
    "new": "gymprecice new my-env --kind openfoam",
    "train": "gymprecice train jet-cylinder --n-envs 4 --timesteps 100000",
    "tune": "gymprecice tune jet-cylinder-fast --algo sac --trials 20",
    "evaluate": "gymprecice evaluate jet-cylinder --episode-time 10 --all-starts",
    "baseline": "gymprecice baseline jet-cylinder --episode-time 10 --all-starts",
    "open-loop": "gymprecice open-loop jet-cylinder --amplitude 0.5 --frequency 3",
    "feedback": "gymprecice feedback jet-cylinder-fast --gain 2 --delay 3 --all-starts",
    "sweep": "gymprecice sweep perpendicular-flap-fast",
    "compare": (
        "gymprecice compare runs/perpendicular-flap-fast/sweep \\\n"
        "    runs/perpendicular-flap-fast/evaluate"
    ),
    "benchmark": "gymprecice benchmark jet-cylinder-fast --seeds 5 --algo ppo,sac --workers 2",
    "time-to-floor": "gymprecice time-to-floor runs/jet-cylinder-fast/train",
    "plot": (
        "gymprecice plot runs/jet-cylinder/train runs/jet-cylinder/evaluate \\\n"
        "    --baseline runs/jet-cylinder/baseline"
    ),
    "ship-policy": (
        "gymprecice ship-policy runs/jet-cylinder/train --name jet-cylinder \\\n"
        "    --evaluation runs/jet-cylinder/evaluate"
    ),
    "policies": "gymprecice policies",
}

#: the width of a usage block: the documentation's code blocks hold 80 characters
USAGE_WIDTH = 80
_CODE_SPAN = re.compile(r"(`[^`]*`)")
_MARKDOWN = re.compile(r"([\\*_\[\]#])")


class ExampleError(RuntimeError):
    """An example of the page that the command line no longer takes."""


def commands(parser: argparse.ArgumentParser | None = None) -> dict[str, argparse.ArgumentParser]:
    """Every command of ``gymprecice`` (its own and its plugins'), in ``--help``'s order."""
    if parser is None:
        from gymprecice.tools.cli import build_parser

        parser = build_parser()
    return dict(_subcommands(parser))


def _subcommands(parser: argparse.ArgumentParser) -> list[tuple[str, argparse.ArgumentParser]]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return list(action.choices.items())
    return []


def _help_of(parser: argparse.ArgumentParser, name: str) -> str:
    """A command's one-line help, as ``gymprecice --help`` lists it."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                if choice.dest == name:
                    return choice.help or ""
    return ""


def _text(text: str) -> str:
    """Help text as Markdown: code spans kept, everything else taken literally; this
    machine's home folder (a help text may name a default under it) written ``~``."""
    out = []
    text = text.replace(str(Path.home()), "~")
    for part in _CODE_SPAN.split(" ".join(text.split())):
        if len(part) > 1 and part.startswith("`") and part.endswith("`"):
            out.append(part)
        else:
            out.append(html.escape(_MARKDOWN.sub(r"\\\1", part), quote=False))
    return "".join(out)


def _cell(text: str) -> str:
    """Text for a table cell: a pipe would end the cell."""
    return _text(text).replace("|", "\\|")


def _default(action: argparse.Action) -> str:
    if action.required:
        return "required"
    if isinstance(action, argparse._StoreTrueAction):
        return "off"
    if isinstance(action, argparse._StoreFalseAction):
        return "on"
    value = action.default
    if value is None or value is argparse.SUPPRESS or value in ([], ()):
        return "none"
    if isinstance(value, (list, tuple)):
        value = " ".join(map(str, value))
    return f"`{value}`"


def _invocation(formatter: argparse.HelpFormatter, action: argparse.Action) -> str:
    return ", ".join(
        f"`{part}`" for part in formatter._format_action_invocation(action).split(", ")
    )


def _usage(parser: argparse.ArgumentParser) -> str:
    formatter = argparse.HelpFormatter(parser.prog, width=USAGE_WIDTH)
    formatter.add_usage(parser.usage, parser._actions, parser._mutually_exclusive_groups)
    return formatter.format_help().strip().replace(str(Path.home()), "~")


def _example(name: str, parser: argparse.ArgumentParser, root: argparse.ArgumentParser) -> str:
    """The command's example, checked against ``root`` (:class:`ExampleError` if refused)."""
    example = EXAMPLES.get(name)
    if example is None:
        words = ["gymprecice", name]
        for action in parser._actions:
            if not action.option_strings and action.required and action.nargs != "*":
                words.append(action.metavar or action.dest.upper())
        example = " ".join(str(w) for w in words)
    argv = shlex.split(example.replace("\\\n", " "))
    if argv[:2] != ["gymprecice", name]:
        raise ExampleError(f"the example of {name!r} does not start with 'gymprecice {name}'")
    with contextlib.redirect_stderr(io.StringIO()) as said:
        try:
            root.parse_args(argv[1:])
        except SystemExit:
            raise ExampleError(
                f"the example of 'gymprecice {name}' no longer parses ({example!r}): "
                f"{said.getvalue().strip().splitlines()[-1]}; update EXAMPLES in "
                "scripts/docs_commands.py"
            ) from None
    return example


def _distribution(parser: argparse.ArgumentParser) -> str | None:
    """The distribution whose code runs the command (its ``func``'s package)."""
    func = parser.get_default("func")
    while hasattr(func, "func"):  # functools.partial
        func = func.func
    module = getattr(func, "__module__", "") or ""
    names = _packages_distributions().get(module.split(".")[0], [])
    return names[0] if names else None


@functools.cache
def _packages_distributions() -> dict[str, list[str]]:
    """Which distribution each top-level package comes from (slow to ask: asked once)."""
    return importlib.metadata.packages_distributions()


def _section(name: str, parser: argparse.ArgumentParser, root: argparse.ArgumentParser) -> str:
    lines = [f"## gymprecice {name}", ""]
    summary = _help_of(root, name)
    if summary:
        lines += [_text(summary[:1].upper() + summary[1:]) + ".", ""]
    description = parser.description or ""
    if description and description.strip().rstrip(".") != summary.strip().rstrip("."):
        lines += [_text(description), ""]
    dist = _distribution(parser)
    if dist and dist != "gymprecice-core":
        lines += [f"Added by the `{dist}` distribution's plugin.", ""]
    lines += ["```text", _usage(parser), "```", ""]
    # a plain formatter: the default has a column of its own (the lab's formatter would
    # add "(default: ...)" to every help)
    formatter = argparse.HelpFormatter(parser.prog)
    rows = []
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction) or action.help == argparse.SUPPRESS:
            continue
        help_text = formatter._expand_help(action) if action.help else ""
        if action.choices and not isinstance(action, argparse._SubParsersAction):
            help_text += f" (one of: {', '.join(map(str, action.choices))})"
        rows.append(
            f"| {_invocation(formatter, action)} | {_default(action)} | {_cell(help_text)} |"
        )
    if rows:
        lines += ["| argument | default | what it does |", "| --- | --- | --- |", *rows, ""]
    lines += ["Example:", "", "```bash", _example(name, parser, root), "```", ""]
    return "\n".join(lines)


def command_reference(parser: argparse.ArgumentParser | None = None) -> str:
    """The page's body: one section per command of ``parser`` (default: ``gymprecice``'s)."""
    if parser is None:
        from gymprecice.tools.cli import build_parser

        parser = build_parser()
    sections = [_section(name, sub, parser) for name, sub in commands(parser).items()]
    index = ", ".join(f"[`{name}`](#gymprecice-{name})" for name in commands(parser))
    return "\n".join([f"Commands: {index}.", "", *sections])
