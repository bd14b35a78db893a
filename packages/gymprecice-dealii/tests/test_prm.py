"""The deal.II parameter-file reader/writer: round trips, edits, edge cases, errors.

The last test compares the reader with deal.II's own ``ParameterHandler`` (a small C++
program built against the installed library); it runs where CMake and deal.II are found.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from gymprecice.plugin.errors import ConfigError
from gymprecice_dealii.prm import ElasticityParameters, PrmError, PrmFile

FLAP_PRM = (
    Path(__file__).resolve().parents[2]
    / "gymprecice-tutorials/src/gymprecice_tutorials/perpendicular_flap/case/solid-dealii/parameters.prm"
)

EDGE_CASES = """\
# Listing of Parameters
set Top level   = 1   # trailing comment
\tSET Tabbed\t= a\tb
subsection Outer   # a comment after the name
  set Value = 2
  set List  = 1, \\
              2,\\
              3     # comment after the continued value
  subsection  Inner  Name
    set Deep key = x = y
    set Empty =
  end
  set After inner = 3
end
subsection Outer
  set Value = 4
end
SUBSECTION Other
  set Comment swallows = 5 # a comment ending in a backslash \\
  set Hidden = 6
END
"""


@pytest.fixture
def edge_file(tmp_path: Path) -> Path:
    path = tmp_path / "edge.prm"
    path.write_bytes(EDGE_CASES.encode())
    return path


def test_perpendicular_flap_file_round_trips_byte_for_byte() -> None:
    raw = FLAP_PRM.read_bytes()
    assert PrmFile.read(FLAP_PRM).text().encode() == raw


def test_perpendicular_flap_file_values() -> None:
    prm = ElasticityParameters.read(FLAP_PRM)
    assert prm.end_time == 5.0
    assert prm.time_step == 0.01
    assert prm.output_interval == 50
    assert prm.output_folder == "dealii-output"
    assert prm.precice_config_file == "../precice-config.xml"
    assert (prm.participant, prm.mesh_name) == ("Solid", "Solid-Mesh")
    assert (prm.read_data, prm.write_data) == ("Force", "Displacement")
    assert prm.get("System properties", "Poisson's ratio") == "0.3"
    assert prm.get("System properties", "body forces") == "0.0, 0.0, 0.0"
    assert prm.missing() == []


def test_edits_change_only_the_values(tmp_path: Path) -> None:
    prm = ElasticityParameters.read(FLAP_PRM)
    prm.end_time = 2.5
    prm.time_step = 0.005
    prm.output_interval = 7
    prm.output_folder = "out/solid"
    prm.precice_config_file = Path("../../env/precice-config.xml")
    prm.participant = "Structure"
    prm.mesh_name = "Structure-Mesh"
    prm.read_data = "Stress"
    prm.write_data = "Displacement"
    before = FLAP_PRM.read_text().splitlines()
    after = prm.text().splitlines()
    changed = [(a, b) for a, b in zip(before, after) if a != b]
    assert len(before) == len(after)
    assert len(changed) == 8  # Write data name was set to its own value
    assert "  set End time        = 2.5" in after
    assert "  set Time step size  = 0.005" in after
    assert "  set precice config-file = ../../env/precice-config.xml" in after
    # what was written reads back
    again = ElasticityParameters.read(prm.write(tmp_path / "parameters.prm"))
    assert (again.end_time, again.time_step, again.output_interval) == (2.5, 0.005, 7)
    assert again.precice_config_file == "../../env/precice-config.xml"
    assert again.participant == "Structure"


def test_integral_floats_are_written_without_a_decimal_point() -> None:
    prm = ElasticityParameters.read(FLAP_PRM)
    prm.end_time = 8.0
    assert "  set End time        = 8" in prm.text().splitlines()


def test_edge_cases_parse_like_dealii(edge_file: Path) -> None:
    prm = PrmFile.read(edge_file)
    assert prm.text() == EDGE_CASES
    assert prm.get((), "Top level") == "1"
    assert prm.get("", "Tabbed") == "a b"  # any whitespace reads as a space
    assert prm.get("Outer", "List") == "1, 2,3"  # trimmed lines joined without a space
    assert prm.get(("Outer", "Inner  Name"), "Deep key") == "x = y"  # the first '=' splits
    assert prm.get(("Outer", "Inner  Name"), "Empty") == ""
    assert prm.get("Outer", "After inner") == "3"
    assert prm.get("Outer", "Value") == "4"  # a later set wins, even in a reopened section
    assert prm.get("Other", "Comment swallows") == "5"
    assert not prm.has("Other", "Hidden")  # the comment's '\' joined it into the comment
    assert prm.sections() == [("Outer",), ("Outer", "Inner  Name"), ("Other",)]
    assert prm.keys("Outer") == ["Value", "List", "After inner"]
    entry = prm.entry("Outer", "List")
    assert (entry.line, entry.last + 1) == (6, 8)


def test_editing_edge_cases_keeps_everything_else(edge_file: Path) -> None:
    prm = PrmFile.read(edge_file)
    prm.set((), "Top level", 42)
    prm.set(("Outer", "Inner  Name"), "Empty", "now set")
    prm.set(("Outer", "Inner  Name"), "Deep key", "z")
    prm.set("Outer", "Value", "5")  # both sets of the key change
    lines = prm.text().split("\n")
    assert lines[1] == "set Top level   = 42   # trailing comment"
    assert lines[9] == "    set Deep key = z"
    assert lines[10] == "    set Empty = now set"
    assert lines[4] == "  set Value = 5"
    assert lines[15] == "  set Value = 5"
    again = PrmFile(prm.text())
    assert again.get("Outer", "Value") == "5"
    assert again.get(("Outer", "Inner  Name"), "Empty") == "now set"
    unchanged = set(range(len(lines))) - {1, 4, 9, 10, 15}
    original = EDGE_CASES.split("\n")
    assert all(lines[i] == original[i] for i in unchanged)


def test_setting_a_continued_value_joins_it_on_one_line_and_keeps_its_comment(
    edge_file: Path,
) -> None:
    prm = PrmFile.read(edge_file)
    prm.set("Outer", "List", "4, 5")
    lines = prm.text().split("\n")
    assert lines[5] == "  set List  = 4, 5  # comment after the continued value"
    assert lines[6] == "  subsection  Inner  Name"
    assert PrmFile(prm.text()).get("Outer", "List") == "4, 5"


def test_crlf_line_endings_survive_edits() -> None:
    prm = PrmFile("subsection Time\r\n  set End time = 1\r\nend\r\n")
    prm.set("Time", "End time", 3)
    assert prm.text() == "subsection Time\r\n  set End time = 3\r\nend\r\n"


def test_unknown_key_names_the_file_and_lists_the_keys_of_its_subsection() -> None:
    prm = ElasticityParameters.read(FLAP_PRM)
    with pytest.raises(PrmError) as caught:
        prm.set("Time", "End tme", 3)
    message = str(caught.value)
    assert str(FLAP_PRM) in message
    assert "'End tme'" in message
    for key in ("End time", "Time step size", "Output interval", "Output folder"):
        assert repr(key) in message
    assert "did you mean 'End time'" in message
    assert isinstance(caught.value, ConfigError)
    assert prm.end_time == 5.0  # nothing changed


def test_unknown_subsection_lists_the_subsections() -> None:
    prm = ElasticityParameters.read(FLAP_PRM)
    with pytest.raises(PrmError, match=r"no subsection 'precice config'.*'precice configuration'"):
        prm.get("precice config", "Mesh name")
    with pytest.raises(PrmError, match="Time"):
        prm.get(("Time", "Nested"), "x")


@pytest.mark.parametrize(
    "value", ["a # b", "line\nbreak", "ends in \\", "carriage\rreturn"], ids=repr
)
def test_values_deal_ii_would_misread_are_refused(value: str) -> None:
    prm = PrmFile("set x = 1\n")
    with pytest.raises(PrmError, match="cannot set 'x'"):
        prm.set((), "x", value)
    assert prm.get((), "x") == "1"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("subsection A\n  set x = 1\n", "subsection 'A' is never closed"),
        ("set x = 1\nend\n", ":2: 'end' without an open subsection"),
        ("subsection A\nendx\n", ":2: unexpected text after 'end'"),
        ("set x\n", ":1: a 'set' line needs 'key = value'"),
        ("Subsection A\nend\n", ":1: cannot read 'Subsection A'"),
        ("x = 1\n", ":1: cannot read 'x = 1'"),
    ],
)
def test_malformed_files_are_reported_with_file_and_line(
    tmp_path: Path, text: str, message: str
) -> None:
    path = tmp_path / "bad.prm"
    path.write_text(text)
    with pytest.raises(PrmError) as caught:
        PrmFile.read(path)
    assert str(path) in str(caught.value)
    assert message in str(caught.value)


def test_typed_getters_report_non_numbers(tmp_path: Path) -> None:
    path = tmp_path / "p.prm"
    path.write_text("subsection Time\n  set End time = soon\n  set Output interval = 2.5\nend\n")
    prm = ElasticityParameters.read(path)
    with pytest.raises(PrmError, match=r"p\.prm:2: 'End time' is 'soon', not a number"):
        _ = prm.end_time
    with pytest.raises(PrmError, match="not an integer"):
        _ = prm.output_interval
    with pytest.raises(PrmError, match="positive integer"):
        prm.output_interval = 0
    assert "precice configuration / Mesh name" in prm.missing()


def test_missing_file_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(PrmError, match="parameter file not found"):
        PrmFile.read(tmp_path / "nope.prm")


def test_include_lines_are_kept_but_not_followed() -> None:
    prm = PrmFile("include other.prm\nset x = 1\n")
    assert prm.includes == ["other.prm"]
    assert prm.text() == "include other.prm\nset x = 1\n"


# -- the reader against deal.II itself -------------------------------------------------------

CHECKER_SOURCE = r"""
#include <deal.II/base/parameter_handler.h>
#include <iostream>
#include <sstream>
// usage: prm_check FILE 'Sub/Sub/key' ...  declares each key, parses FILE, prints values
static std::vector<std::string> split(const std::string &s) {
  std::vector<std::string> parts; std::stringstream in(s); std::string item;
  while (std::getline(in, item, '/')) parts.push_back(item);
  return parts;
}
int main(int argc, char **argv) {
  dealii::ParameterHandler prm;
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1) {
      try { prm.parse_input(argv[1]); }
      catch (std::exception &e) { std::cout << "ERROR" << std::endl; return 1; }
    }
    for (int i = 2; i < argc; ++i) {
      auto parts = split(argv[i]);
      for (size_t j = 0; j + 1 < parts.size(); ++j) prm.enter_subsection(parts[j]);
      if (pass == 0) prm.declare_entry(parts.back(), "<unset>", dealii::Patterns::Anything());
      else std::cout << prm.get(parts.back()) << std::endl;
      for (size_t j = 0; j + 1 < parts.size(); ++j) prm.leave_subsection();
    }
  }
}
"""

CHECKER_CMAKE = """
cmake_minimum_required(VERSION 3.13)
find_package(deal.II REQUIRED HINTS $ENV{DEAL_II_DIR})
deal_ii_initialize_cached_variables()
project(prm_check CXX)
add_executable(prm_check prm_check.cc)
deal_ii_setup_target(prm_check)
"""


@pytest.fixture(scope="module")
def dealii_checker(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if shutil.which("cmake") is None:
        pytest.skip("cmake is not installed; it builds the deal.II comparison program")
    source = tmp_path_factory.mktemp("prm_check")
    (source / "prm_check.cc").write_text(CHECKER_SOURCE)
    (source / "CMakeLists.txt").write_text(CHECKER_CMAKE)
    build = source / "build"
    configure = subprocess.run(
        ["cmake", "-S", str(source), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release"],
        capture_output=True,
        text=True,
    )
    if configure.returncode != 0:
        pytest.skip("deal.II's CMake configuration was not found (install libdeal.ii-dev)")
    compiled = subprocess.run(["cmake", "--build", str(build)], capture_output=True, text=True)
    assert compiled.returncode == 0, compiled.stdout[-2000:] + compiled.stderr[-2000:]
    return build / "prm_check"


@pytest.mark.slow
@pytest.mark.parametrize("which", ["edge cases", "perpendicular flap"])
def test_values_agree_with_dealii_parameter_handler(
    dealii_checker: Path, edge_file: Path, which: str
) -> None:
    path = edge_file if which == "edge cases" else FLAP_PRM
    prm = PrmFile.read(path)
    entries = {"/".join([*e.section, e.key]): e.value for e in prm.entries()}
    if which == "edge cases":
        entries["Other/Hidden"] = "<unset>"  # swallowed by the comment: deal.II never sets it
    done = subprocess.run(
        [str(dealii_checker), str(path), *entries], capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.split("\n")[: len(entries)] == list(entries.values())
