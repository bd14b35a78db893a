"""SB3's logger for ``gymprecice train``: TensorBoard, ``progress.csv`` and, verbose, stdout.

SB3's CSV writer truncates its file when opened, so a resumed run (a new *segment*)
writes ``progress.<segment>.csv`` and, when it ends, appends it to ``progress.csv`` under
the union of both headers. A segment killed too hard to merge leaves its own file.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path
from typing import Any

__all__ = ["PROGRESS_NAME", "merge_progress", "segment_logger"]

PROGRESS_NAME = "progress.csv"


def _segment_csv(out: Path, segment: int) -> Path:
    return out / (PROGRESS_NAME if segment == 1 else f"progress.{segment}.csv")


def segment_logger(out: Path, algo: str, segment: int, verbose: int) -> Any:
    """A logger writing TensorBoard (``tb/<algo>_<segment>``), CSV and, if verbose, stdout."""
    from stable_baselines3.common.logger import (
        CSVOutputFormat,
        HumanOutputFormat,
        Logger,
        TensorBoardOutputFormat,
    )

    tb = out / "tb" / f"{algo}_{segment}"
    tb.mkdir(parents=True, exist_ok=True)
    formats: list[Any] = [
        CSVOutputFormat(str(_segment_csv(out, segment))),
        TensorBoardOutputFormat(str(tb)),
    ]
    if verbose >= 1:
        formats.append(HumanOutputFormat(sys.stdout))
    logger = Logger(folder=str(out), output_formats=formats)
    logger.set_level(10 if verbose >= 2 else 20)
    return logger


def merge_progress(out: Path, segment: int) -> None:
    """Append segment ``segment``'s CSV rows to ``progress.csv`` (segment 1 writes it)."""
    part = _segment_csv(out, segment)
    whole = out / PROGRESS_NAME
    if segment == 1 or not part.is_file():
        return
    rows: list[dict[str, str]] = []
    fields: list[str] = []
    for path in (whole, part):
        if not path.is_file():
            continue
        with path.open(newline="") as handle:
            reader = csv.DictReader(handle)
            fields += [f for f in reader.fieldnames or [] if f not in fields]
            rows += list(reader)
    tmp = whole.with_suffix(".csv.tmp")
    with tmp.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)
    tmp.replace(whole)
    part.unlink()
