"""The lab's documentation stays true to the code: the Lab reference's table of card fields,
and the commands "Writing an environment" runs on its example package.

docs/reference/lab.md lists every field of :class:`gymprecice.card.EnvCard`, in the
dataclass's order, with the type it is declared with; the commands it says read a field are
commands of the ``gymprecice`` command line. The lab commands printed at the end of
docs/writing-an-env.md parse with that command line, and the refusal it quotes is the one
the card gives. (tests/test_third_party_lab.py runs the commands themselves.)
"""

from __future__ import annotations

import argparse
import re
import shlex
from dataclasses import fields
from pathlib import Path

import pytest

from gymprecice.plugin.card import CardError, EnvCard

ROOT = Path(__file__).resolve().parents[1]
LAB_PAGE = ROOT / "docs" / "reference" / "lab.md"
ENV_PAGE = ROOT / "docs" / "writing-an-env.md"
LAB_SECTION = "## Train, evaluate and benchmark it"


def _table(page: Path) -> list[list[str]]:
    """The rows of the page's field table (header and rule left out), cells stripped;
    ``\\|`` inside a cell is a ``|`` of the cell."""
    rows = []
    for line in page.read_text().splitlines():
        if line.startswith("| `"):
            cells = re.split(r"(?<!\\)\|", line.strip()[1:-1])
            rows.append([c.strip().replace("\\|", "|") for c in cells])
    return rows


def _commands() -> set[str]:
    from gymprecice.tools.cli import build_parser

    parser = build_parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return set(sub.choices)


def _section(page: Path, heading: str) -> str:
    text = page.read_text()
    assert heading in text, f"{page.name} has no section {heading!r}"
    return text.split(heading, 1)[1].split("\n## ", 1)[0]


def test_the_lab_reference_lists_every_card_field_with_its_type() -> None:
    rows = _table(LAB_PAGE)
    declared = [(f"`{f.name}`", f"`{f.type}`") for f in fields(EnvCard)]
    assert [(row[0], row[1]) for row in rows] == declared, (
        "docs/reference/lab.md's table must list EnvCard's fields in order, each with its "
        "declared type: add or change the row of the field that differs"
    )


def test_the_commands_said_to_read_a_field_exist() -> None:
    commands = _commands()
    lab = {"train", "evaluate", "baseline", "open-loop", "feedback", "sweep", "compare",
           "benchmark", "time-to-floor", "plot", "ship-policy", "policies"}  # fmt: skip
    assert lab <= commands, sorted(lab - commands)
    for row in _table(LAB_PAGE):
        named = {re.split(r"\s", code)[0] for code in re.findall(r"`([^`]+)`", row[-1])}
        named = {n for n in named if re.fullmatch(r"[a-z]+(-[a-z]+)*", n)}
        assert named <= commands, (row[0], sorted(named - commands))


def test_the_pages_lab_commands_parse() -> None:
    """Every ``gymprecice`` line of the section parses with the command line, the package it
    installs is the repository's example, and no line needs a flag that does not exist."""
    from gymprecice.tools.cli import build_parser

    section = _section(ENV_PAGE, LAB_SECTION)
    (block,) = re.findall(r"```bash\n(.*?)```", section, re.S)
    lines = [line.split("#", 1)[0].strip() for line in block.splitlines() if line.strip()]
    install, *commands = lines
    assert install == "pip install ./gymprecice-heated-rod"
    assert (ROOT / "examples" / "gymprecice-heated-rod" / "pyproject.toml").is_file()
    assert {shlex.split(c)[1] for c in commands} == {
        "train", "evaluate", "baseline", "sweep", "benchmark",
    }  # fmt: skip
    for command in commands:
        argv = shlex.split(command)
        assert argv[0] == "gymprecice" and argv[2] == "heated-rod", command
        try:
            build_parser().parse_args(argv[1:])
        except SystemExit:
            pytest.fail(f"docs/writing-an-env.md: `{command}` does not parse")


def test_the_quoted_refusal_is_the_cards() -> None:
    section = _section(ENV_PAGE, LAB_SECTION)
    (quoted,) = re.findall(r"```text\n(.*?)\n```", section, re.S)
    with pytest.raises(CardError) as refusal:
        EnvCard(name="heated-rod").require("reference", "time-to-floor", "heatedrod/HeatedRod-v0")
    # printed wrapped, to fit the page: the words are the one line the command prints
    assert quoted.split() == f"gymprecice time-to-floor: {refusal.value}".split()
