"""Build the documentation site strictly, and say where each problem is.

    python scripts/build_docs.py [--site-dir DIR] [--repo-url URL [--edit-uri PATH]]

runs ``mkdocs build --strict`` on mkdocs.yml: a broken link, a missing page, an anchor that
is not there or a docstring cross-reference that does not resolve fails the build. MkDocs
names the page of a broken link but not its line, so each of its warnings is reported
again as ``docs/PAGE.md:LINE: warning`` (the lines where the link's target is written).
The build needs no network (no external inventories, the theme's fonts off) and writes to
``site/`` (ignored by git). The test suite runs it (tests/test_docs_site.py).

The site offers the source it documents: before the build, the committed tree (``git
archive HEAD``; the files on disk outside a git checkout) is packed as
``docs/downloads/gymprecice-source.tar.gz`` (ignored by git), which the site serves and Get
started links, so a reader of the site alone can set up a machine.

A site built for a published copy of the project names its repository: ``--repo-url``
links it in every page's header, and each page gets an "edit this page" button that opens
its Markdown source there (``--edit-uri``, relative to the address; the default,
``edit/main/docs/``, is GitHub's and GitLab's form). Without an address, neither appears.

A machine without the site's dependencies gets their names and the command that installs
them (docs/requirements.txt; scripts/setup.sh installs it into .venv).
"""

from __future__ import annotations

import argparse
import importlib.metadata
import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlsplit

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
REQUIREMENTS = DOCS / "requirements.txt"

_PINNED = re.compile(r"^\s*([A-Za-z0-9_.-]+)\s*==\s*([^\s;#]+)")
#: MkDocs' and mkdocs-autorefs' warnings that name a page and a target but not a line
_PAGE_WARNINGS = (
    re.compile(
        r"Doc file '(?P<page>[^']+)' contains (?:a|an unrecognized relative) link '(?P<target>[^']+)'"
    ),
    re.compile(
        r"mkdocs_autorefs: (?P<page>[^:\s]+\.md): Could not find cross-reference target '(?P<target>[^']+)'"
    ),
)
#: mkdocs-autorefs' warning for a docstring: the page, and the source file at the line where
#: the object (or its docstring) begins, not the line that writes the reference
_DOCSTRING_WARNING = re.compile(
    r"from (?P<source>[^\s:]+\.py):(?P<line>\d+): \([^)]*\) "
    r"Could not find cross-reference target '(?P<target>[^']+)'"
)


@dataclass(frozen=True)
class Requirement:
    name: str
    version: str


def requirements(path: Path = REQUIREMENTS) -> list[Requirement]:
    """The pinned distributions the site is built with."""
    found = []
    for line in path.read_text().splitlines():
        match = _PINNED.match(line)
        if match:
            found.append(Requirement(match.group(1), match.group(2)))
    return found


def missing_requirements(path: Path = REQUIREMENTS) -> list[str]:
    """``name==version`` of each requirement that is absent or another version here."""
    missing = []
    for req in requirements(path):
        try:
            installed = importlib.metadata.version(req.name)
        except importlib.metadata.PackageNotFoundError:
            missing.append(f"{req.name}=={req.version} (not installed)")
            continue
        if installed != req.version:
            missing.append(f"{req.name}=={req.version} (found {installed})")
    return missing


def install_advice(missing: list[str]) -> str:
    """What to tell a machine without the site's dependencies."""
    return (
        f"the documentation site needs {', '.join(missing)} in {sys.executable}: run "
        f"`{sys.executable} -m pip install -r {REQUIREMENTS.relative_to(ROOT)}` "
        "(bash scripts/setup.sh does it)"
    )


def locate(warning: str, docs_dir: Path = DOCS) -> list[str]:
    """``docs/PAGE:LINE: warning`` for each line of the page that writes the warning's target.

    A broken reference in a docstring is placed at the line of the source file that writes
    it (mkdocs-autorefs names the line where the object begins). A warning that names no
    page (griffe's, already placed) or whose target is not written where it points comes
    back unchanged.
    """
    docstring = _DOCSTRING_WARNING.search(warning)
    if docstring is not None:
        return [_in_source(docstring, warning.strip())]
    for pattern in _PAGE_WARNINGS:
        match = pattern.search(warning)
        if match is None:
            continue
        page = docs_dir / match["page"]
        if not page.is_file():
            break
        target = match["target"]
        needles = (f"]({target})", f"]({target} ", f"][{target}]", f"[{target}][]", f"<{target}>")
        lines = page.read_text().splitlines()
        hits = [i for i, line in enumerate(lines, 1) if any(n in line for n in needles)]
        if not hits:
            hits = [i for i, line in enumerate(lines, 1) if target in line]
        if hits:
            where = (
                page.relative_to(docs_dir.parent) if page.is_relative_to(docs_dir.parent) else page
            )
            return [f"{where}:{line}: {warning.strip()}" for line in hits]
        break
    return [warning.strip()]


def _in_source(match: re.Match[str], warning: str) -> str:
    """``FILE:LINE: warning`` at the first line from the object's start that writes the target."""
    source, start = Path(match["source"]), int(match["line"])
    try:
        lines = source.read_text().splitlines()
    except OSError:
        return warning
    target = match["target"]
    hits = [i for i, line in enumerate(lines, 1) if i >= start and target in line]
    if not hits:
        return warning
    where = source.relative_to(ROOT) if source.is_relative_to(ROOT) else source
    return f"{where}:{hits[0]}: {warning}"


@dataclass(frozen=True)
class BuildResult:
    ok: bool
    problems: list[str]
    output: str


#: the source archive the site serves (Get started links it)
SOURCE_ARCHIVE = DOCS / "downloads" / "gymprecice-source.tar.gz"
#: what a source archive made outside a git checkout leaves out (build outputs, venvs)
_NOT_SOURCE = {
    ".git",
    ".venv",
    ".venv-rllib",
    ".pytest_cache",
    ".ruff_cache",
    "site",
    "runs",
    "build",
    "dist",
    "__pycache__",
}


def write_source_archive(path: Path = SOURCE_ARCHIVE) -> Path:
    """Pack the source under ``gymprecice/`` into ``path``: ``git archive HEAD`` in a git
    checkout, else every file below the root but build outputs and virtual environments."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")  # builds side by side: their own
    git = subprocess.run(
        ["git", "archive", "--format=tar.gz", "--prefix=gymprecice/", "-o", str(tmp), "HEAD"],
        cwd=ROOT,
        capture_output=True,
    )
    if git.returncode != 0:
        import tarfile

        with tarfile.open(tmp, "w:gz") as tar:
            for file in sorted(ROOT.rglob("*")):
                relative = file.relative_to(ROOT)
                built = bool(_NOT_SOURCE & set(relative.parts)) or any(
                    part.endswith(".egg-info") for part in relative.parts
                )
                served = relative.parts[:2] == ("docs", "downloads")  # this very archive
                if file.is_file() and not built and not served:
                    tar.add(file, arcname=f"gymprecice/{relative}")
    tmp.replace(path)
    return path


#: Where an edit link points, relative to the repository's address (GitHub's and GitLab's).
DEFAULT_EDIT_URI = "edit/main/docs/"


def repository_env(repo_url: str | None, edit_uri: str | None = None) -> dict[str, str]:
    """The variables mkdocs.yml reads for the repository link and the edit links (none
    without an address: an edit link needs somewhere to go)."""
    if not repo_url:
        return {}
    if not repo_url.startswith(("https://", "http://")):
        raise ValueError(f"--repo-url must be an http(s) address, not {repo_url!r}")
    # the header shows the repository's path (owner/name), not the host's name
    name = urlsplit(repo_url).path.strip("/") or urlsplit(repo_url).netloc
    return {
        "GYMPRECICE_REPO_URL": repo_url,
        "GYMPRECICE_REPO_NAME": name,
        "GYMPRECICE_EDIT_URI": edit_uri or DEFAULT_EDIT_URI,
    }


def build(
    site_dir: Path | None = None, repo_url: str | None = None, edit_uri: str | None = None
) -> BuildResult:
    """``mkdocs build --strict``; ``problems`` are its warnings and errors, placed by line."""
    missing = missing_requirements()
    if missing:
        return BuildResult(False, [install_advice(missing)], "")
    write_source_archive()
    command = [sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", "mkdocs.yml"]
    if site_dir is not None:
        command += ["--site-dir", str(site_dir)]
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "NO_COLOR": "1"}
    for variable in ("GYMPRECICE_REPO_URL", "GYMPRECICE_REPO_NAME", "GYMPRECICE_EDIT_URI"):
        env.pop(variable, None)
    env.update(repository_env(repo_url, edit_uri))
    proc = subprocess.run(
        command, cwd=ROOT, capture_output=True, text=True, env=env, stdin=subprocess.DEVNULL
    )
    output = proc.stdout + proc.stderr
    problems = []
    for line in output.splitlines():
        if line.startswith(("WARNING", "ERROR")):
            problems += locate(line.split("-", 1)[1] if " -  " in line else line)
    if proc.returncode != 0 and not problems:
        problems = output.strip().splitlines()[-10:]
    return BuildResult(proc.returncode == 0, problems, output)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n", 1)[0])
    parser.add_argument("--site-dir", type=Path, default=None, help="where the site goes (site/)")
    parser.add_argument(
        "--repo-url",
        default=None,
        help="the repository's address: a link in every page's header, and edit links",
    )
    parser.add_argument(
        "--edit-uri",
        default=None,
        help=f"a page's source, relative to --repo-url (default {DEFAULT_EDIT_URI})",
    )
    args = parser.parse_args(argv)
    if args.edit_uri and not args.repo_url:
        parser.error("--edit-uri needs --repo-url: an edit link is relative to the address")
    try:
        repository_env(args.repo_url, args.edit_uri)
    except ValueError as exc:
        parser.error(str(exc))
    result = build(args.site_dir, args.repo_url, args.edit_uri)
    for problem in result.problems:
        print(problem, file=sys.stderr)
    if result.ok:
        print(f"documentation site built in {args.site_dir or ROOT / 'site'}")
    return 0 if result.ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
