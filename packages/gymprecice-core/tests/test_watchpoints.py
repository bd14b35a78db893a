"""The watch-point reader on logs laid out exactly as preCICE v3 writes them.

``write_like_precice`` reproduces ``io::TXTTableWriter`` as ``WatchPoint`` drives it: a
header without a newline, then each row *preceded* by a newline, values ``%15.8e`` two
spaces apart, so a finished log never ends in a newline.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

from gymprecice.plugin.solver import OutputReader
from gymprecice.plugin.watchpoints import (
    WatchPointError,
    WatchPointLog,
    WatchPointTimeoutError,
    parse_header,
    watch_point_file_name,
)

# 2-D Solid-Mesh using Displacement then Force, as in the perpendicular-flap tutorial.
COLUMNS = [
    "Time",
    "Coordinate0",
    "Coordinate1",
    "Displacement0",
    "Displacement1",
    "Force0",
    "Force1",
]


def header(columns: list[str]) -> str:
    return "".join(f"  {name}" for name in columns)


def row(values: list[float]) -> str:
    return "\n" + "  ".join(f"{v:15.8e}" for v in values)


def flap_row(t: float) -> list[float]:
    return [t, 0.0, 1.0, 0.1 * t, -0.01 * t, 2.0 + t, -1.5e-3]


def write_like_precice(path: Path, times: list[float]) -> str:
    text = header(COLUMNS) + "".join(row(flap_row(t)) for t in times)
    path.write_text(text)
    return text


@pytest.fixture
def log_path(tmp_path: Path) -> Path:
    return tmp_path / watch_point_file_name("Solid", "Flap-Tip")


def test_file_name_is_preCICEs() -> None:
    assert watch_point_file_name("Solid", "Flap-Tip") == "precice-Solid-watchpoint-Flap-Tip.log"


def test_reads_every_row_of_a_finished_log_without_trailing_newline(log_path: Path) -> None:
    text = write_like_precice(log_path, [0.0, 0.01, 0.02])
    assert not text.endswith("\n")
    reader = WatchPointLog(log_path)
    rows = reader.read_new()
    assert rows.shape == (3, 7)
    np.testing.assert_allclose(rows[:, 0], [0.0, 0.01, 0.02])
    np.testing.assert_allclose(rows[2], flap_row(0.02))
    assert reader.columns == COLUMNS
    assert reader.read_new().shape == (0, 7)  # nothing new


def test_fields_group_vector_columns_by_the_mesh_dimension(log_path: Path) -> None:
    write_like_precice(log_path, [0.0, 0.5])
    reader = WatchPointLog(log_path)
    reader.read_new()
    assert set(reader.fields) == {"Time", "Coordinate", "Displacement", "Force"}
    np.testing.assert_allclose(reader.field("Displacement"), [[0.0, 0.0], [0.05, -0.005]])
    np.testing.assert_allclose(reader.field("Time"), [0.0, 0.5])
    assert reader.field("Coordinate").shape == (2, 2)
    with pytest.raises(KeyError, match="Displacment"):
        reader.field("Displacment")


def test_parse_header_keeps_scalars_ending_in_a_digit_scalar() -> None:
    fields = parse_header(
        ["Time", "Coordinate0", "Coordinate1", "Coordinate2", "Pressure2", "V0", "V1", "V2"]
    )
    assert (fields["Coordinate"].start, fields["Coordinate"].width) == (1, 3)
    assert fields["Pressure2"].width == 1
    assert (fields["V"].start, fields["V"].width) == (5, 3)


def test_missing_file_reads_empty_until_it_appears(log_path: Path) -> None:
    reader = WatchPointLog(log_path)
    assert reader.read_new().shape == (0, 0)
    assert reader.latest_time is None
    write_like_precice(log_path, [0.0])
    assert reader.read_new().shape == (1, 7)


def test_header_alone_is_not_read_until_the_first_row_starts(log_path: Path) -> None:
    log_path.write_text(header(COLUMNS))  # preCICE has not flushed a row yet
    reader = WatchPointLog(log_path)
    assert reader.read_new().shape == (0, 0)
    assert reader.columns is None


def test_half_written_row_waits_for_the_rest(log_path: Path) -> None:
    full = header(COLUMNS) + row(flap_row(0.0)) + row(flap_row(0.01))
    cut = len(full) - 9  # inside the last value: "-1.50000000e-03" loses "00e-03"
    log_path.write_text(full[:cut])
    reader = WatchPointLog(log_path)
    first = reader.read_new()
    np.testing.assert_allclose(first[:, 0], [0.0])
    with log_path.open("a") as handle:
        handle.write(full[cut:])
    second = reader.read_new()
    np.testing.assert_allclose(second, [flap_row(0.01)])
    np.testing.assert_allclose(reader.data[:, 0], [0.0, 0.01])


SIX_VALUES = "\n 1.00000000e-02  0.00000000e+00  1.00000000e+00  1.0e-03  -1.0e-04  2.01e+00"


@pytest.mark.parametrize(
    "cut_text",
    [
        "\n 1.00000000e-02  0.00000000e+00",  # too few values
        SIX_VALUES + "  -1.5e-0",  # the seventh value's exponent is cut
        SIX_VALUES + "  -1.5",  # the seventh value's mantissa only
        "\n",  # only the newline that starts the next row
    ],
    ids=["few values", "exponent cut", "mantissa only", "newline only"],
)
def test_incomplete_last_rows_are_never_returned(log_path: Path, cut_text: str) -> None:
    log_path.write_text(header(COLUMNS) + row(flap_row(0.0)) + cut_text)
    reader = WatchPointLog(log_path)
    assert reader.read_new().shape == (1, 7)
    assert reader.latest_time == 0.0


def test_appending_rows_one_poll_at_a_time_gives_each_row_once(log_path: Path) -> None:
    log_path.write_text(header(COLUMNS) + row(flap_row(0.0)))
    reader = WatchPointLog(log_path)
    seen = [reader.read_new()]
    for k in range(1, 6):
        with log_path.open("a") as handle:
            handle.write(row(flap_row(k * 0.01)))
        seen.append(reader.read_new())
    times = np.concatenate([block[:, 0] for block in seen])
    np.testing.assert_allclose(times, [0.0, 0.01, 0.02, 0.03, 0.04, 0.05])


def test_wait_until_returns_once_the_row_is_written(log_path: Path) -> None:
    log_path.write_text(header(COLUMNS) + row(flap_row(0.0)))
    reader = WatchPointLog(log_path)

    def solver_writes_late() -> None:
        time.sleep(0.2)
        with log_path.open("a") as handle:
            handle.write(row(flap_row(0.01)))
            handle.flush()
            time.sleep(0.1)
            handle.write(row(flap_row(0.02)))

    writer = threading.Thread(target=solver_writes_late)
    writer.start()
    try:
        rows = reader.wait_until(0.02, timeout=10.0)
    finally:
        writer.join()
    np.testing.assert_allclose(rows[:, 0], [0.0, 0.01, 0.02])
    assert reader.latest_time == pytest.approx(0.02)


def test_wait_until_waits_for_a_file_that_does_not_exist_yet(log_path: Path) -> None:
    reader = WatchPointLog(log_path)
    timer = threading.Timer(0.2, write_like_precice, args=(log_path, [0.0]))
    timer.start()
    try:
        rows = reader.wait_until(0.0, timeout=10.0)
    finally:
        timer.join()
    assert rows.shape == (1, 7)


def test_wait_until_matches_times_printed_to_nine_digits(log_path: Path) -> None:
    # The env's time 1/3 is in the log as 3.33333333e-01, a little less than 1/3.
    write_like_precice(log_path, [0.0, 1.0 / 3.0])
    reader = WatchPointLog(log_path)
    assert reader.wait_until(1.0 / 3.0, timeout=0.0).shape == (2, 7)
    assert reader.latest_time < 1.0 / 3.0
    with pytest.raises(WatchPointTimeoutError):  # but a whole later window is not there
        reader.wait_until(1.0 / 3.0 + 1e-6, timeout=0.0)


def test_wait_until_times_out_and_says_what_it_saw(log_path: Path) -> None:
    reader = WatchPointLog(log_path)
    with pytest.raises(WatchPointTimeoutError, match="does not exist"):
        reader.wait_until(0.0, timeout=0.05)
    write_like_precice(log_path, [0.0, 0.01])
    with pytest.raises(WatchPointTimeoutError, match=r"last complete row is at time 0\.01"):
        reader.wait_until(0.02, timeout=0.05)
    with pytest.raises(TimeoutError):  # also a builtin TimeoutError
        reader.wait_until(1.0, timeout=0.0)


def test_a_replaced_file_is_read_from_its_start(log_path: Path) -> None:
    write_like_precice(log_path, [0.0, 0.01, 0.02])
    reader = WatchPointLog(log_path)
    assert len(reader.read_new()) == 3
    log_path.unlink()
    write_like_precice(log_path, [0.0])  # a new episode
    rows = reader.read_new()
    np.testing.assert_allclose(rows[:, 0], [0.0])
    assert len(reader.data) == 1


def test_rows_with_the_wrong_number_of_values_are_an_error(log_path: Path) -> None:
    log_path.write_text(header(COLUMNS) + "\n 1.0e+00  2.0e+00" + row(flap_row(0.01)))
    with pytest.raises(WatchPointError, match=r":2: 2 values, but the header names 7"):
        WatchPointLog(log_path).read_new()


def test_a_file_without_the_time_column_is_an_error(log_path: Path) -> None:
    log_path.write_text("x y z\n1 2 3")
    with pytest.raises(WatchPointError, match="not a preCICE watch-point log"):
        WatchPointLog(log_path).read_new()


def test_it_is_an_output_reader_and_refuses_reads_after_close(log_path: Path) -> None:
    reader = WatchPointLog.for_watch_point(log_path.parent, "Solid", "Flap-Tip")
    assert isinstance(reader, OutputReader)
    assert reader.path == log_path
    reader.close()
    with pytest.raises(ValueError, match="closed"):
        reader.read_new()


def test_nan_values_from_a_diverging_solver_are_rows_too(log_path: Path) -> None:
    text = (
        header(COLUMNS)
        + row(flap_row(0.0))
        + "\n"
        + "  ".join(f"{v:>15}" for v in ["1.00000000e-02", "0", "1", "nan", "-nan", "inf", "nan"])
    )
    log_path.write_text(text)
    rows = WatchPointLog(log_path).read_new()
    assert rows.shape == (2, 7)
    assert np.isnan(rows[1, 3])


def test_wait_until_keeps_the_rows_of_a_solver_running_ahead_for_the_next_step(
    log_path: Path,
) -> None:
    # The solver is a window ahead: when the env reads the step ending at 0.01, the row of
    # 0.02 is already in the file. It belongs to the next step, whenever it was written.
    write_like_precice(log_path, [0.0, 0.01, 0.02])
    reader = WatchPointLog(log_path)
    step = reader.wait_until(0.01, timeout=0.0)
    np.testing.assert_allclose(step[:, 0], [0.0, 0.01])
    assert reader.latest_time == pytest.approx(0.01)
    np.testing.assert_allclose(reader.data[-1], flap_row(0.01))  # .data: what was handed out
    # asked again for the same step (the reward after the observation): the same rows
    np.testing.assert_array_equal(reader.wait_until(0.01, timeout=0.0), step)
    with log_path.open("a") as handle:
        handle.write(row(flap_row(0.03)))
    np.testing.assert_allclose(reader.wait_until(0.02, timeout=0.0)[:, 0], [0.02])
    np.testing.assert_allclose(reader.read_new()[:, 0], [0.03])  # the rest, whatever its time


def test_a_step_s_rows_do_not_depend_on_how_far_the_solver_got(log_path: Path) -> None:
    def steps(lead: int) -> list[list[float]]:
        """Read steps of 0.01 while the solver is always ``lead`` rows ahead."""
        times = [round(0.01 * k, 10) for k in range(8)]
        path = log_path.with_name(f"lead-{lead}.log")
        path.write_text(header(COLUMNS))
        reader = WatchPointLog(path)
        written, out = 0, []
        for k in range(1, 5):
            while written < min(len(times), k + 1 + lead):
                with path.open("a") as handle:
                    handle.write(row(flap_row(times[written])))
                written += 1
            out.append(reader.wait_until(times[k], timeout=0.0)[:, 0].tolist())
        return out

    assert steps(0) == steps(1) == steps(3)
    assert steps(2)[1] == pytest.approx([0.02])


def test_read_new_then_wait_until_hands_out_no_row_twice(log_path: Path) -> None:
    write_like_precice(log_path, [0.0, 0.01, 0.02])
    reader = WatchPointLog(log_path)
    assert len(reader.read_new()) == 3
    assert reader.wait_until(0.02, timeout=0.0).shape == (0, 7)
