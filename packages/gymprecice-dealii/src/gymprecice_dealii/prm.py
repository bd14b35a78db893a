"""Read and edit deal.II parameter files (``parameters.prm``) without disturbing them.

deal.II's ``ParameterHandler`` format has no maintained Python reader, and the deal.II-preCICE
adapter's ``elasticity`` program takes all its settings from one such file, so an env that
points the solid at its own preCICE configuration, or shortens its output, must edit it.
Edits are surgical: only the characters of the changed value move, every comment, blank
line and alignment stays byte for byte, and :meth:`PrmFile.text` of an unedited file is the
file itself.

The syntax, as deal.II 9.4's ``ParameterHandler::parse_input`` reads it (checked against
the library)::

    # a comment runs from the first '#' to the end of the line ('\\#' is no escape)
    # names keep inner spaces: 'precice configuration'
    subsection Time
      # key and value are trimmed; the first '=' splits
      set End time        = 5
      set body forces     = 0.0, \\
                            0.0,0.0 # a line ending in '\\' continues on the next one
      subsection Nested             # subsections nest; each needs its 'end'
        set x = 1
      end
    end

* Each physical line is trimmed, then a trailing ``\\`` joins it to the next trimmed line
  (no space is inserted). This happens *before* comments are removed, so a comment that
  ends in ``\\`` swallows the following line.
* Keywords are ``subsection``/``SUBSECTION``, ``set``/``SET``, ``end``/``END`` and
  ``include``/``INCLUDE`` (kept, but not followed). Any whitespace counts as a space.
* Keys are matched exactly (case and inner spaces), as deal.II does; a later ``set`` of
  the same key overrides an earlier one.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from gymprecice.plugin import ConfigError

__all__ = [
    "ElasticityParameters",
    "PrmEntry",
    "PrmError",
    "PrmFile",
    "Section",
]

#: a subsection path: ``()`` is the top level, ``("Time",)``, ``("Outer", "Inner")``
Section = tuple[str, ...]
_WHITESPACE = re.compile(r"\s")


class PrmError(ConfigError):
    """A parameter file cannot be read, or an edit names a key the file does not have."""


@dataclass(frozen=True)
class PrmEntry:
    """One ``set`` statement: where it is, what it sets, and its raw position.

    ``first`` and ``last`` are 0-based indices of the physical lines it spans (more than one
    with continuation lines); ``line`` is the 1-based number of its first line.
    """

    section: Section
    key: str
    value: str
    first: int
    last: int

    @property
    def line(self) -> int:
        return self.first + 1


def _section(section: str | Sequence[str]) -> Section:
    """``"Time"`` -> ``("Time",)``; ``""`` -> ``()``; a sequence is a nested path."""
    if isinstance(section, str):
        return (section,) if section else ()
    return tuple(section)


def _label(section: Section) -> str:
    return " / ".join(repr(s) for s in section) if section else "the top level"


def _format(value: object) -> str:
    """A value as deal.II reads it back: integral floats without a ".0", the rest as str()."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and value.is_integer() and abs(value) < 1e15:
        return str(int(value))
    return str(value)


class PrmFile:
    """A parsed parameter file that can be queried and edited in place."""

    def __init__(self, text: str, path: str | Path | None = None) -> None:
        self.path = Path(path) if path is not None else None
        self._lines = text.split("\n")
        self._entries: list[PrmEntry] = []
        self._sections: list[Section] = []
        self.includes: list[str] = []
        self._parse()

    # -- reading and writing ---------------------------------------------------------------
    @classmethod
    def read(cls, path: str | Path) -> PrmFile:
        path = Path(path)
        try:
            text = path.read_bytes().decode("utf-8")
        except FileNotFoundError:
            raise PrmError(f"{path}: parameter file not found") from None
        except UnicodeDecodeError as exc:
            raise PrmError(f"{path}: not a text file ({exc.reason})") from None
        return cls(text, path)

    def text(self) -> str:
        return "\n".join(self._lines)

    def write(self, path: str | Path | None = None) -> Path:
        """Write to ``path`` (default: the file it was read from); returns the path."""
        target = Path(path) if path is not None else self.path
        if target is None:
            raise ValueError("this parameter file was parsed from text; give a path to write it")
        target.write_bytes(self.text().encode("utf-8"))
        return target

    # -- queries ---------------------------------------------------------------------------
    @property
    def where(self) -> str:
        return str(self.path) if self.path else "<parameter text>"

    def entries(self) -> list[PrmEntry]:
        return list(self._entries)

    def sections(self) -> list[Section]:
        """Every subsection path, in order of first appearance (without the top level)."""
        return list(self._sections)

    def keys(self, section: str | Sequence[str] = ()) -> list[str]:
        """Keys set directly in ``section``, in file order, each once."""
        path = _section(section)
        return list(dict.fromkeys(e.key for e in self._entries if e.section == path))

    def has(self, section: str | Sequence[str], key: str) -> bool:
        path = _section(section)
        return any(e.section == path and e.key == key for e in self._entries)

    def entry(self, section: str | Sequence[str], key: str) -> PrmEntry:
        """The effective (last) ``set`` of ``key``; unknown names raise :class:`PrmError`."""
        matches = list(self._find(section, key))
        return matches[-1]

    def get(self, section: str | Sequence[str], key: str) -> str:
        return self.entry(section, key).value

    def get_float(self, section: str | Sequence[str], key: str) -> float:
        entry = self.entry(section, key)
        try:
            return float(entry.value)
        except ValueError:
            raise PrmError(
                f"{self.where}:{entry.line}: {entry.key!r} is {entry.value!r}, not a number"
            ) from None

    def get_int(self, section: str | Sequence[str], key: str) -> int:
        entry = self.entry(section, key)
        try:
            return int(entry.value)
        except ValueError:
            raise PrmError(
                f"{self.where}:{entry.line}: {entry.key!r} is {entry.value!r}, not an integer"
            ) from None

    # -- editing ---------------------------------------------------------------------------
    def set(self, section: str | Sequence[str], key: str, value: object) -> None:
        """Change the value of an existing key, keeping the rest of the file as it is.

        Only keys the file already sets can be changed, so a misspelt key fails here, with
        the keys of that subsection, instead of being silently added and then rejected (or
        worse, ignored) by the solver.
        """
        text = _format(value)
        if "\n" in text or "\r" in text or "#" in text or text.rstrip().endswith("\\"):
            raise PrmError(
                f"{self.where}: cannot set {key!r} to {text!r}: a value cannot hold a line "
                "break or '#', nor end in '\\' (deal.II would read a comment or a continuation)"
            )
        text = text.strip()
        # Later lines first, so the indices of earlier entries stay valid.
        for entry in sorted(self._find(section, key), key=lambda e: e.first, reverse=True):
            self._replace(entry, text)
        self._parse()

    def _replace(self, entry: PrmEntry, value: str) -> None:
        raw = self._lines[entry.first]
        if entry.first == entry.last:
            self._lines[entry.first] = _with_value(raw, value)
            return
        # A value spread over continuation lines becomes one line; a comment on the last
        # of them is kept.
        last = self._lines[entry.last]
        ending = "\r" if last.endswith("\r") else ""
        body = self._lines[entry.first : entry.last]
        hash_at = last.find("#")
        if hash_at >= 0 and not any("#" in line for line in body):
            ending = "  " + last[hash_at:]
        equals = raw.find("=")
        comment = raw.find("#")
        if equals >= 0 and (comment < 0 or equals < comment):
            head = raw[: equals + 1]
        else:
            indent = raw[: len(raw) - len(raw.lstrip())]
            head = f"{indent}set {entry.key} ="
        self._lines[entry.first : entry.last + 1] = [f"{head} {value}{ending}"]

    def _find(self, section: str | Sequence[str], key: str) -> Iterator[PrmEntry]:
        path = _section(section)
        if path and path not in self._sections:
            raise PrmError(
                f"{self.where}: no subsection {_label(path)}; the subsections are "
                f"{[' / '.join(s) for s in self._sections]}"
                + _suggest(" / ".join(path), [" / ".join(s) for s in self._sections])
            )
        matches = [e for e in self._entries if e.section == path and e.key == key]
        if not matches:
            known = self.keys(path)
            raise PrmError(
                f"{self.where}: {_label(path)} has no key {key!r}; its keys are {known}"
                + _suggest(key, known)
            )
        yield from matches

    # -- parsing ---------------------------------------------------------------------------
    def _parse(self) -> None:
        entries: list[PrmEntry] = []
        sections: list[Section] = []
        includes: list[str] = []
        stack: list[str] = []
        joined = ""
        start: int | None = None
        for index, raw in enumerate(self._lines):
            stripped = raw.strip()
            if stripped.endswith("\\"):
                if start is None:
                    start, joined = index, ""
                joined += stripped[:-1]
                continue
            if start is not None:
                logical, first = joined + stripped, start
                start, joined = None, ""
            else:
                logical, first = stripped, index
            self._statement(logical, first, index, stack, entries, sections, includes)
        if start is not None:  # the file ends inside a continuation
            self._statement(joined, start, len(self._lines) - 1, stack, entries, sections, includes)
        if stack:
            raise PrmError(
                f"{self.where}: subsection {_label(tuple(stack))} is never closed; add "
                f"{len(stack)} 'end' line(s) (deal.II needs as many 'end' as 'subsection')"
            )
        self._entries, self._sections, self.includes = entries, sections, includes

    def _statement(
        self,
        logical: str,
        first: int,
        last: int,
        stack: list[str],
        entries: list[PrmEntry],
        sections: list[Section],
        includes: list[str],
    ) -> None:
        line = _WHITESPACE.sub(" ", logical).split("#", 1)[0].strip()
        if not line:
            return
        where = f"{self.where}:{first + 1}"
        if line.startswith(("subsection ", "SUBSECTION ")):
            stack.append(line[len("subsection ") :].strip())
            if tuple(stack) not in sections:
                sections.append(tuple(stack))
        elif line.startswith(("end", "END")):
            if line not in ("end", "END"):
                raise PrmError(f"{where}: unexpected text after 'end': {line!r}")
            if not stack:
                raise PrmError(f"{where}: 'end' without an open subsection")
            stack.pop()
        elif line.startswith(("set ", "SET ")):
            body = line[len("set ") :]
            equals = body.find("=")
            if equals < 0:
                raise PrmError(f"{where}: a 'set' line needs 'key = value', got {line!r}")
            entries.append(
                PrmEntry(
                    section=tuple(stack),
                    key=body[:equals].strip(),
                    value=body[equals + 1 :].strip(),
                    first=first,
                    last=last,
                )
            )
        elif line.startswith(("include", "INCLUDE")):
            includes.append(line[len("include") :].strip())
        else:
            raise PrmError(
                f"{where}: cannot read {line!r}; lines are 'subsection NAME', 'set KEY = VALUE', "
                "'end' or comments starting with '#'"
            )


def _with_value(raw: str, value: str) -> str:
    """Put ``value`` in place of the value of one physical ``set`` line, keeping the rest."""
    equals = raw.index("=")
    comment = raw.find("#", equals)
    stop = comment if comment >= 0 else len(raw.rstrip("\r"))
    ending = raw[stop:]
    segment = raw[equals + 1 : stop]
    lead = segment[: len(segment) - len(segment.lstrip())] or " "
    trail = segment[len(segment.rstrip()) :]
    if not segment.strip():  # 'set key =' with nothing after it, or only spaces
        lead, trail = " ", (" " if comment >= 0 else "")
    return f"{raw[: equals + 1]}{lead}{value}{trail}{ending}"


def _suggest(word: str, choices: Sequence[str]) -> str:
    close = difflib.get_close_matches(word, list(choices), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


class ElasticityParameters(PrmFile):
    """``parameters.prm`` of the deal.II-preCICE adapter's ``elasticity`` program.

    Typed access to the settings an environment changes; the key names are the adapter's
    (``include/adapter/parameters.cc``). Everything else stays reachable through
    :meth:`get` and :meth:`set`.
    """

    TIME = "Time"
    PRECICE = "precice configuration"
    KEYS: dict[str, tuple[str, str]] = {
        "end_time": (TIME, "End time"),
        "time_step": (TIME, "Time step size"),
        "output_interval": (TIME, "Output interval"),
        "output_folder": (TIME, "Output folder"),
        "precice_config_file": (PRECICE, "precice config-file"),
        "participant": (PRECICE, "Participant name"),
        "mesh_name": (PRECICE, "Mesh name"),
        "read_data": (PRECICE, "Read data name"),
        "write_data": (PRECICE, "Write data name"),
    }

    def missing(self) -> list[str]:
        """``'subsection / key'`` of every adapter setting this file lacks."""
        return [f"{s} / {k}" for s, k in self.KEYS.values() if not self.has(s, k)]

    @property
    def end_time(self) -> float:
        return self.get_float(*self.KEYS["end_time"])

    @end_time.setter
    def end_time(self, value: float) -> None:
        self.set(*self.KEYS["end_time"], float(value))

    @property
    def time_step(self) -> float:
        return self.get_float(*self.KEYS["time_step"])

    @time_step.setter
    def time_step(self, value: float) -> None:
        self.set(*self.KEYS["time_step"], float(value))

    @property
    def output_interval(self) -> int:
        return self.get_int(*self.KEYS["output_interval"])

    @output_interval.setter
    def output_interval(self, value: int) -> None:
        if int(value) != value or value < 1:
            raise PrmError(
                f"{self.where}: Output interval must be a positive integer, got {value!r}"
            )
        self.set(*self.KEYS["output_interval"], int(value))

    @property
    def output_folder(self) -> str:
        return self.get(*self.KEYS["output_folder"])

    @output_folder.setter
    def output_folder(self, value: str | Path) -> None:
        self.set(*self.KEYS["output_folder"], str(value))

    @property
    def precice_config_file(self) -> str:
        return self.get(*self.KEYS["precice_config_file"])

    @precice_config_file.setter
    def precice_config_file(self, value: str | Path) -> None:
        self.set(*self.KEYS["precice_config_file"], str(value))

    @property
    def participant(self) -> str:
        return self.get(*self.KEYS["participant"])

    @participant.setter
    def participant(self, value: str) -> None:
        self.set(*self.KEYS["participant"], value)

    @property
    def mesh_name(self) -> str:
        return self.get(*self.KEYS["mesh_name"])

    @mesh_name.setter
    def mesh_name(self, value: str) -> None:
        self.set(*self.KEYS["mesh_name"], value)

    @property
    def read_data(self) -> str:
        return self.get(*self.KEYS["read_data"])

    @read_data.setter
    def read_data(self, value: str) -> None:
        self.set(*self.KEYS["read_data"], value)

    @property
    def write_data(self) -> str:
        return self.get(*self.KEYS["write_data"])

    @write_data.setter
    def write_data(self, value: str) -> None:
        self.set(*self.KEYS["write_data"], value)
