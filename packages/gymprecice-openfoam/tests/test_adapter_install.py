"""The OpenFOAM-preCICE adapter's install step: how it chooses a route and fails clearly.

The real build (Debian's source package route) runs in the set-up and every coupled test
uses its library; here the decisions around it are checked without compiling anything.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from gymprecice import stack
from gymprecice.tools.stack import install
from gymprecice_openfoam import adapter_install
from gymprecice_openfoam.installation import OpenFOAMInstallation


@pytest.fixture
def prefix(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv(stack.PREFIX_ENV, str(tmp_path / "stack"))
    monkeypatch.setenv(stack.DOWNLOAD_ENV, "0")
    monkeypatch.delenv(stack.SOURCES_ENV, raising=False)
    return tmp_path / "stack"


def installation(root: Path, layout: str) -> OpenFOAMInstallation:
    (root / "etc").mkdir(parents=True)
    (root / "etc" / "controlDict").write_text("")
    return OpenFOAMInstallation(project_dir=root, layout=layout, env={"PATH": str(root / "bin")})


def test_openfoam_without_headers_and_no_source_package_says_what_to_install(
    prefix, tmp_path, monkeypatch
):
    found = installation(tmp_path / "OpenFOAM-v2306", "bin-on-path")
    monkeypatch.setattr(adapter_install, "find_openfoam", lambda: found)
    step = adapter_install.openfoam_adapter_step()
    step.found = lambda: None
    step.requires = ()
    [result] = install([step], say=lambda _line: None)
    assert result.status == "failed"
    assert str(found.project_dir) in result.failure
    assert "ships no headers and no wmake" in result.failure
    assert "GYMPRECICE_OPENFOAM_BASHRC" in result.failure
    assert stack.stamp_of(step) is None


def test_debian_openfoam_without_deb_src_names_the_fix(prefix, tmp_path, monkeypatch):
    found = installation(tmp_path / "share" / "openfoam", "debian")
    monkeypatch.setattr(adapter_install, "find_openfoam", lambda: found)
    monkeypatch.setattr(adapter_install, "_debian_openfoam_version", lambda: "9999.1-1+b1")
    mirror = Path(__file__).resolve().parents[4] / "shared" / "vendor"
    if not (mirror / adapter_install.ADAPTER_ARCHIVE.filename).is_file():
        pytest.skip("no offline mirror of the adapter's release archive beside the checkout")
    monkeypatch.setenv(stack.SOURCES_ENV, str(mirror))
    # apt-get cannot fetch a source version that does not exist: the message says what to do
    step = adapter_install.openfoam_adapter_step()
    step.found = lambda: None
    step.requires = ()
    [result] = install([step], say=lambda _line: None)
    assert result.status == "failed"
    assert "openfoam 9999.1-1 could not be fetched" in result.failure  # +b1: a binary rebuild
    assert "deb-src" in result.failure and "GYMPRECICE_SOURCES" in result.failure


def test_ln_include_dirs_follow_the_adapter_make_options(tmp_path):
    src = tmp_path / "src"
    for d in ("OpenFOAM", "OSspecific/POSIX", "finiteVolume", "TurbulenceModels/incompressible"):
        (src / d).mkdir(parents=True)
    options = tmp_path / "options"
    options.write_text(
        "EXE_INC = -I$(LIB_SRC)/finiteVolume/lnInclude \\\n"
        "    -I$(LIB_SRC)/TurbulenceModels/incompressible/lnInclude \\\n"
        "    -I$(LIB_SRC)/triSurface/lnInclude\n"
    )
    dirs = adapter_install._ln_include_dirs(options, src)
    assert dirs == [
        src / "OpenFOAM",
        src / "OSspecific" / "POSIX",
        src / "finiteVolume",
        src / "TurbulenceModels" / "incompressible",
    ]  # triSurface does not exist in this release: skipped
