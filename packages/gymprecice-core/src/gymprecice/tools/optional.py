"""What to ``pip install`` when an optional dependency is missing: one line, not a traceback.

gymprecice's distributions keep their heavy dependencies optional (Stable-Baselines3 and
torch for training, Ray for clusters, pytest for the conformance suite), so code can meet a
``ModuleNotFoundError`` on a machine where the user installed only what they needed. They
should then read the one command that fixes it.

The command comes from the installed metadata, not from a table kept by hand: the
distribution that owns the failing code declares the missing requirement, either plainly or
under an extra, so the advice is exactly what its ``pyproject.toml`` says
(``pip install 'gymprecice-core[sb3]'``). Only the import name -> distribution name step needs
a table (``yaml`` is PyYAML), and only a module listed there is translated: any other missing
module is a bug and keeps its traceback.
"""

from __future__ import annotations

import importlib.util
import re
from importlib import metadata

__all__ = [
    "COMMANDS_ELSEWHERE",
    "PROVIDERS",
    "install_command",
    "missing_command",
    "missing_dependency",
    "optional_import_error",
]

#: Import names of the optional dependencies, and the distribution that provides each.
PROVIDERS: dict[str, str] = {
    "stable_baselines3": "stable-baselines3",
    "torch": "torch",
    "yaml": "PyYAML",
    "ray": "ray",
    "pettingzoo": "pettingzoo",
    "pytest": "pytest",
    "scipy": "scipy",
    "tensorboard": "tensorboard",
    "tqdm": "tqdm",
    "rich": "rich",
    "matplotlib": "matplotlib",
    "torchrl": "torchrl",
    "imageio": "imageio",
    "moviepy": "moviepy",
    "gymprecice_lab": "gymprecice-lab",
}

#: Commands another distribution adds, by the import name that provides them: typed where it
#: is not installed, they name the install instead of argparse's "invalid choice".
COMMANDS_ELSEWHERE: dict[str, str] = dict.fromkeys(
    (
        "train",
        "evaluate",
        "baseline",
        "open-loop",
        "feedback",
        "sweep",
        "compare",
        "benchmark",
        "time-to-floor",
        "plot",
        "ship-policy",
        "policies",
    ),
    "gymprecice_lab",
)

#: torch from the default index pulls about 3 GB of CUDA packages; this is the CPU build.
TORCH_CPU = "pip install torch --index-url https://download.pytorch.org/whl/cpu"

#: what pulls torch in: its install deserves the CPU-only route
_PULLS_TORCH = frozenset({"torch", "stable_baselines3", "torchrl", "gymprecice_lab"})

_GYMPRECICE_DISTS = ("gymprecice-core", "gymprecice-lab", "gymprecice-tutorials")


def _normalise(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _requirements(dist_name: str) -> list[tuple[str, str | None]]:
    """``(name, extra or None)`` for each ``Requires-Dist`` of an installed distribution."""
    try:
        requires = metadata.requires(dist_name) or []
    except metadata.PackageNotFoundError:
        return []
    out = []
    for line in requires:
        name = re.match(r"\s*([A-Za-z0-9][A-Za-z0-9._-]*)", line)
        if name is None:
            continue
        extra = re.search(r"extra\s*==\s*[\"']([^\"']+)[\"']", line)
        out.append((_normalise(name.group(1)), extra.group(1) if extra else None))
    return out


def _owners(module: str | None) -> list[str]:
    """The distributions that install the top-level package of ``module`` (may be none)."""
    if not module:
        return []
    try:
        found = metadata.packages_distributions().get(module.split(".", 1)[0], [])
    except Exception:  # a broken installation must not hide the advice
        return []
    return list(dict.fromkeys(found))


def install_command(missing: str, owner_module: str | None = None) -> str | None:
    """The ``pip install ...`` that brings ``missing`` (an import name), or ``None``.

    Looks for the requirement in the distribution that owns ``owner_module`` first, then
    in gymprecice's own distributions, and names the extra that declares it; where nothing
    declares it, the provider itself. ``None`` for a module that is not a known optional
    dependency.
    """
    top = missing.split(".", 1)[0]
    provider = PROVIDERS.get(top)
    if provider is None:
        return None
    wanted = _normalise(provider)
    for dist in dict.fromkeys([*_owners(owner_module), *_GYMPRECICE_DISTS]):
        for name, extra in _requirements(dist):
            if name == wanted:
                return f"pip install '{dist}[{extra}]'" if extra else f"pip install '{dist}'"
    return f"pip install '{provider}'"


def missing_dependency(exc: BaseException, owner_module: str | None = None) -> str | None:
    """One line for a ``ModuleNotFoundError`` of an optional dependency, else ``None``.

    ``owner_module`` is the module of the code that imported it (a command's function), so
    the advice names that distribution's extra.
    """
    if not isinstance(exc, ModuleNotFoundError) or not exc.name:
        return None
    command = install_command(exc.name, owner_module)
    if command is None:
        return None
    top = exc.name.split(".", 1)[0]
    return f"{top} is not installed: {command}{_torch_note(top)}"


def missing_command(command: str) -> str | None:
    """One line for a command that a distribution which is not installed would add."""
    module = COMMANDS_ELSEWHERE.get(command)
    if module is None or importlib.util.find_spec(module) is not None:
        return None
    provider = PROVIDERS.get(module, module)
    return (
        f"'{command}' is a command of {provider}, which is not installed: "
        f"{install_command(module)}{_torch_note(module)}"
    )


def _torch_note(top: str) -> str:
    if top in _PULLS_TORCH and importlib.util.find_spec("torch") is None:
        return f" (for the CPU-only torch, first: {TORCH_CPU})"
    return ""


def optional_import_error(exc: ModuleNotFoundError, needed_by: str) -> ModuleNotFoundError:
    """A ``ModuleNotFoundError`` saying which install brings what ``needed_by`` imports.

    For modules such as :mod:`gymprecice.sb3` whose import needs an extra: raise it
    ``from None`` in place of the bare error. It keeps ``name``, so the command line turns it
    into the same one line.
    """
    hint = install_command(exc.name or "", needed_by) or "pip install the missing package"
    return ModuleNotFoundError(
        f"{needed_by} needs {exc.name}, which is not installed: {hint}", name=exc.name
    )
