"""What a pip user meets: a missing extra in one line, and another ``gymprecice`` distribution.

Both are read from installed metadata, so the tests install fake distributions: a
``.dist-info`` directory written into a temporary ``sys.path`` entry is, to
``importlib.metadata``, an installed distribution.
"""

from __future__ import annotations

import base64
import hashlib
import json
import subprocess
import sys
from pathlib import Path

import pytest

from gymprecice import optional, plugins
from gymprecice.plugin.hookspecs import hookimpl
from gymprecice.plugin.manager import DISABLE_ENV_VAR, temporary_plugin
from gymprecice.tools.cli import main
from gymprecice.tools.distribution import CLASH_FIX, name_clash


@pytest.fixture(autouse=True)
def fresh(monkeypatch: pytest.MonkeyPatch):
    """A freshly loaded plugin manager with core's plugin only (hermetic)."""
    monkeypatch.setattr(plugins, "_manager", None)
    monkeypatch.setenv(DISABLE_ENV_VAR, "1")
    return monkeypatch


def fake_distribution(
    site: Path, name: str, version: str, *, requires: tuple[str, ...] = (), files: str = ""
) -> Path:
    """Write ``<name>-<version>.dist-info`` into ``site`` (a directory on sys.path)."""
    info = site / f"{name.replace('-', '_')}-{version}.dist-info"
    info.mkdir(parents=True)
    lines = ["Metadata-Version: 2.1", f"Name: {name}", f"Version: {version}"]
    lines += [f"Requires-Dist: {r}" for r in requires]
    (info / "METADATA").write_text("\n".join(lines) + "\n")
    (info / "RECORD").write_text(files)
    return info


def _hash(data: bytes) -> str:
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"sha256={digest}"


# -- a missing optional dependency ---------------------------------------------------------------


def test_the_install_command_comes_from_the_owners_extra(fresh, tmp_path: Path) -> None:
    site = tmp_path / "site"
    fake_distribution(
        site,
        "toy-lab",
        "1.0",
        requires=("numpy>=1.24", 'PyYAML>=6; extra == "yaml"', "stable-baselines3>=2.3"),
        files="toy_lab/__init__.py,,\n",
    )
    fresh.syspath_prepend(str(site))
    # declared under an extra: that extra; declared plainly: the distribution itself
    assert optional.install_command("yaml", "toy_lab.cli") == "pip install 'toy-lab[yaml]'"
    assert optional.install_command("stable_baselines3.common", "toy_lab") == (
        "pip install 'toy-lab'"
    )
    # declared nowhere: the provider itself; not an optional dependency: no advice at all
    assert optional.install_command("torchrl", "toy_lab") == "pip install 'torchrl'"
    assert optional.install_command("gymnasium", "toy_lab") is None


def test_a_command_missing_an_extra_says_what_to_install_in_one_line(capsys, fresh) -> None:
    class Needs:
        @hookimpl
        def gymprecice_register_commands(self, subparsers):
            p = subparsers.add_parser("needs-yaml")
            p.set_defaults(func=self.run)
            p = subparsers.add_parser("buggy")
            p.set_defaults(func=self.buggy)

        @staticmethod
        def run(args):
            import yaml_which_is_not_there  # noqa: F401  # pragma: no cover

        @staticmethod
        def buggy(args):
            raise ModuleNotFoundError("No module named 'gymprecice.typo'", name="gymprecice.typo")

    fresh.setitem(optional.PROVIDERS, "yaml_which_is_not_there", "PyYAML-not-there")
    with temporary_plugin(Needs(), "needs"):
        status = main(["needs-yaml"])
        out, err = capsys.readouterr()
        assert status == 2 and out == ""
        assert err.count("\n") == 1, err  # one line, no traceback
        assert err.startswith("gymprecice needs-yaml: error: yaml_which_is_not_there is not ")
        assert "pip install 'PyYAML-not-there'" in err
        # a module that is no optional dependency is a bug: its traceback stays
        with pytest.raises(ModuleNotFoundError, match=r"gymprecice\.typo"):
            main(["buggy"])


def test_gymprecice_sb3_without_stable_baselines3_names_the_extra() -> None:
    code = (
        "import sys; sys.modules['stable_baselines3'] = None\n"
        "try:\n    import gymprecice.sb3\n"
        "except ModuleNotFoundError as exc:\n    print(exc.name); print(exc)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    name, message = proc.stdout.strip().splitlines()[-2:]
    assert name.startswith("stable_baselines3")
    assert message.startswith("gymprecice.sb3 needs stable_baselines3")
    assert "pip install '" in message


def test_the_conformance_suite_without_pytest_names_the_extra() -> None:
    code = (
        "import sys; sys.modules['pytest'] = None\n"
        "try:\n    import gymprecice.testing.conformance\n"
        "except ModuleNotFoundError as exc:\n    print(exc)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    message = proc.stdout.strip().splitlines()[-1]
    assert message.startswith("gymprecice.testing.conformance needs pytest")
    assert "pip install '" in message


# -- another distribution named gymprecice -------------------------------------------------------


def test_no_clash_in_this_environment() -> None:
    assert name_clash() is None


def _doctor(capsys, *argv: str) -> tuple[int, str]:
    status = main(["doctor", *argv])
    return status, capsys.readouterr().out


def test_doctor_names_a_distribution_called_gymprecice_and_the_fix(
    capsys, fresh, tmp_path: Path
) -> None:
    site = tmp_path / "site"
    init = b"from gymprecice.core import Adapter\n"
    fake_distribution(
        site, "gymprecice", "0.1.0", files=f"gymprecice/__init__.py,{_hash(init)},{len(init)}\n"
    )
    fresh.syspath_prepend(str(site))
    status, out = _doctor(capsys, "--json")
    (check,) = [c for c in json.loads(out)["checks"] if c["name"] == "gymprecice package"]
    assert status == 1 and check["ok"] is False and check["required"] is True
    assert "gymprecice 0.1.0" in check["detail"]
    assert check["advice"] == CLASH_FIX
    assert "pip uninstall gymprecice" in CLASH_FIX
    assert "pip install --force-reinstall gymprecice-core" in CLASH_FIX
    status, text = _doctor(capsys)
    assert status == 1 and "[MISSING] gymprecice package (required)" in text
    assert f"-> {CLASH_FIX}" in text


def test_a_distribution_of_another_name_that_owns_the_package_is_named(
    fresh, tmp_path: Path
) -> None:
    site = tmp_path / "site"
    fake_distribution(site, "gym-precice-fork", "2.0", files="gymprecice/__init__.py,,\n")
    fresh.syspath_prepend(str(site))
    clash = name_clash()
    assert clash is not None and "gym-precice-fork 2.0" in clash


def test_an_overwritten_or_deleted_init_file_is_detected(fresh, tmp_path: Path) -> None:
    site = tmp_path / "site"
    ours = b'__version__ = "0.2.0"\n'
    fake_distribution(
        site, "gymprecice-core", "0.2.0", files=f"gymprecice/__init__.py,{_hash(ours)},9\n"
    )
    fresh.syspath_prepend(str(site))
    package = tmp_path / "installed" / "gymprecice"
    package.mkdir(parents=True)
    (package / "__init__.py").write_bytes(ours)
    assert name_clash([str(package)]) is None  # the file core's record lists
    (package / "__init__.py").write_bytes(b"from gymprecice.core import Adapter\n")
    clash = name_clash([str(package)])
    assert clash is not None and "not the file gymprecice-core installed" in clash
    (package / "__init__.py").unlink()
    clash = name_clash([str(package)])
    assert clash is not None and "__init__.py is missing" in clash


def test_a_command_of_a_distribution_not_installed_names_the_install(capsys, fresh) -> None:
    fresh.setitem(optional.COMMANDS_ELSEWHERE, "toy-train", "toy_lab_not_installed")
    fresh.setitem(optional.PROVIDERS, "toy_lab_not_installed", "toy-lab")
    status = main(["toy-train", "--double"])
    out, err = capsys.readouterr()
    assert status == 2 and out == ""
    assert err == (
        "gymprecice: error: 'toy-train' is a command of toy-lab, which is not installed: "
        "pip install 'toy-lab'\n"
    )
    # a command no distribution offers stays argparse's usage error
    with pytest.raises(SystemExit) as exit_:
        main(["toy-nothing"])
    assert exit_.value.code == 2 and "invalid choice" in capsys.readouterr().err
