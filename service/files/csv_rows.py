"""Reading uploaded CSV tables: the header check, the data rows with their line numbers, the 422 error.

Shared by the demonstration upload (`csv_demos`) and the COP recording upload (`recordings`).
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Iterator, Sequence
from typing import Any

from service.problems import Unprocessable
from service.settings import Settings
from service.sizes import check_request_memory

MAX_CELL_BYTES = csv.field_size_limit()
"""Longest cell a CSV may hold (Python's csv limit, 128 KiB): a longer one is a 422 naming its line."""
MAX_ERRORS = 20
"""At most this many malformed rows are reported for one upload."""


def csv_error(items: Iterable[tuple[str, str]]) -> Unprocessable:
    """A 422 listing (pointer, message) pairs of a CSV that could not be read; the detail repeats the first."""
    errors = [{"pointer": p, "message": m} for p, m in items]
    return Unprocessable(f"The CSV is invalid: {errors[0]['message']}", errors=errors)


def _checked(reader: Any) -> Iterator[list[str]]:
    """The rows of a `csv.reader`, its errors (a cell over `MAX_CELL_BYTES`, e.g. an unclosed quote that runs
    on) as a 422 naming the CSV line, and bytes that are not UTF-8 as a 422."""
    while True:
        try:
            row = next(reader)
        except StopIteration:
            return
        except UnicodeDecodeError as exc:
            raise csv_error([("", f"the file is not UTF-8 text ({exc})")]) from exc
        except csv.Error as exc:
            raise csv_error(
                [
                    (
                        "",
                        f"CSV line {reader.line_num}: cannot be read ({exc}); a cell holds at most "
                        f"{MAX_CELL_BYTES // 1024} KiB (is a quote left open?)",
                    )
                ]
            ) from exc
        yield row


def check_csv_memory(data: bytes, *, row_bytes: int, settings: Settings) -> None:
    """422 at /file before a CSV is parsed if its rows (counted by line breaks) would take more than the
    per-request memory budget at `row_bytes` each."""
    rows = data.count(b"\n") + 1
    check_request_memory(f"reading {rows:,} CSV rows", rows * row_bytes, settings, pointer="/file")


def csv_rows(
    data: bytes, *, required: Sequence[str], optional: Sequence[str] = ()
) -> tuple[set[str], Iterator[tuple[int, dict[str, str]]]]:
    """(columns present, rows) of a UTF-8 CSV: each non-blank data row as (CSV line, {column: stripped cell}),
    read and decoded one line at a time (no decoded copy of the whole file).

    Raises a 422 when the file is not UTF-8, holds a NUL character, or its header lacks a required column (header names are
    case-insensitive; other columns are ignored), and, while iterating, at a row with more non-empty cells
    than the header has columns (a shifted or merged row must not be read as something else) or a cell that
    cannot be read (`_checked`).
    """
    nul = data.find(b"\x00")
    if nul >= 0:
        line = data.count(b"\n", 0, nul) + 1
        raise csv_error([("", f"CSV line {line}: contains a NUL character, which text may not hold")])
    text = io.TextIOWrapper(io.BytesIO(data), encoding="utf-8-sig", newline="")  # decoded line by line
    reader = _checked(csv.reader(text))
    header = [h.strip().lower() for h in next(reader, [])]
    missing = [c for c in required if c not in header]
    if missing:
        raise csv_error(
            [
                (
                    "",
                    f"CSV line 1: the header must name the columns {', '.join(required)}; missing {', '.join(missing)}",
                )
            ]
        )
    col = {c: header.index(c) for c in (*required, *optional) if c in header}

    def rows() -> Iterator[tuple[int, dict[str, str]]]:
        for line, row in enumerate(reader, start=2):
            if any(cell.strip() for cell in row):
                if len(row) > len(header) and any(cell.strip() for cell in row[len(header) :]):
                    raise csv_error(
                        [
                            (
                                "",
                                f"CSV line {line}: has {len(row)} cells but the header names {len(header)} "
                                "columns; remove the extra cells (or quote a cell that contains a comma)",
                            )
                        ]
                    )
                yield line, {c: (row[i].strip() if i < len(row) else "") for c, i in col.items()}

    return set(col), rows()
