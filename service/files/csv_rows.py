"""Reading uploaded CSV tables: the delimiter, the header check, the data rows with their line numbers, the 422
error.

Shared by the demonstration upload (`csv_demos`) and the COP recording upload (`recordings`). The delimiter
(comma, tab or semicolon) is read from the header line with `csv.Sniffer`; a header cell may carry a unit
after its name, ``Fx[N]`` or ``t (s)``.
"""

from __future__ import annotations

import csv
import io
import itertools
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from service.problems import Unprocessable
from service.settings import Settings
from service.sizes import first_too_large, request_memory_issues

MAX_CELL_BYTES = csv.field_size_limit()
"""Longest cell a CSV may hold (Python's csv limit, 128 KiB): a longer one is a 422 naming its line."""
MAX_ERRORS = 20
"""At most this many malformed rows are reported for one upload."""
DELIMITERS = {",": "comma", "\t": "tab", ";": "semicolon"}
"""The delimiters a CSV may use, and their names in messages."""
UNIT_BRACKETS = {"]": "[", ")": "("}
"""Closing → opening bracket of a unit after a header cell's name: ``COPx[cm]``, ``t (s)``."""
SHOWN_COLUMNS = 12
"""At most this many header cells are quoted in a message about the header."""
SNIFFED_CHARS = 4096
"""Characters of the header line `csv.Sniffer` reads: its regular expressions take time quadratic in the
length of a line full of quotes (45 s for 100,000), 0.1 s at most for this many."""


def csv_error(items: Iterable[tuple[str, str]]) -> Unprocessable:
    """A 422 listing (pointer, message) pairs of a CSV that could not be read; the detail repeats the first. An
    error of the whole file (pointer "") points at the upload's ``file`` part."""
    errors = [{"pointer": p or "/file", "message": m} for p, m in items]
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
    first_too_large(
        request_memory_issues(f"reading {rows:,} CSV rows", rows * row_bytes, settings, pointer="/file")
    )


def delimiter_of(line: str) -> str:
    """The delimiter of a CSV's header line (`DELIMITERS`, by `csv.Sniffer` on its first `SNIFFED_CHARS`); a
    comma where it cannot tell (a header of one column)."""
    try:
        return csv.Sniffer().sniff(line[:SNIFFED_CHARS], delimiters="".join(DELIMITERS)).delimiter
    except csv.Error:
        return ","


def column_name(cell: str, aliases: Mapping[str, str] = {}) -> tuple[str, str | None]:
    """A header cell as (name, unit): the name lower-cased, its unit suffix cut off and an alias replaced by
    its column (``Time[s]`` → ``("t", "s")`` with ``{"time": "t"}``); ``x`` → ``("x", None)``."""
    text, unit = cell.strip(), None
    opener = UNIT_BRACKETS.get(text[-1:])
    start = text.rfind(opener) if opener else -1
    if opener and start > 0 and text[-1] not in text[start + 1 : -1] and text[:start].strip():
        text, unit = text[:start], text[start + 1 : -1].strip()
    name = text.strip().lower()
    return aliases.get(name, name), unit or None


@dataclass(frozen=True)
class CsvHeader:
    """A CSV's header line: its delimiter, its cells as written, and each cell's name and unit (`column_name`)."""

    delimiter: str
    cells: list[str]
    names: list[str]
    units: list[str | None]

    def described(self) -> str:
        """The cells and the delimiter, for a message: ``read the columns 'a', 'b' (delimiter: tab)``."""
        shown = ", ".join(repr(c[:40]) for c in self.cells[:SHOWN_COLUMNS])
        more = f", … ({len(self.cells)} in all)" if len(self.cells) > SHOWN_COLUMNS else ""
        return f"read the columns {shown}{more} (delimiter: {DELIMITERS[self.delimiter]})"


def header_of(cells: list[str], delimiter: str, aliases: Mapping[str, str] = {}) -> CsvHeader:
    """The `CsvHeader` of a header row's cells."""
    read = [column_name(c, aliases) for c in cells]
    return CsvHeader(delimiter, [c.strip() for c in cells], [n for n, _ in read], [u for _, u in read])


def csv_header(data: bytes, aliases: Mapping[str, str] = {}) -> CsvHeader:
    """The header of a CSV's first line (bytes that are not UTF-8 replaced), without reading the rest."""
    end = data.find(b"\n")  # the first line alone is decoded, the rest never copied
    first = data[: end if end >= 0 else len(data)].decode("utf-8-sig", errors="replace")
    delimiter = delimiter_of(first)
    return header_of(next(csv.reader([first], delimiter=delimiter), []), delimiter, aliases)


@dataclass(frozen=True)
class CsvTable:
    """A CSV's header, the index of each wanted column it has, and its data rows (`csv_table`)."""

    header: CsvHeader
    columns: dict[str, int]
    rows: Iterator[tuple[int, dict[str, str]]]

    @property
    def units(self) -> dict[str, str]:
        """The unit the header gives each wanted column that has one."""
        return {c: unit for c, i in self.columns.items() if (unit := self.header.units[i]) is not None}


def csv_table(
    data: bytes, *, required: Sequence[str], optional: Sequence[str] = (), aliases: Mapping[str, str] = {}
) -> CsvTable:
    """A UTF-8 CSV whose delimiter is read from its header line (`delimiter_of`): each non-blank data row as
    (CSV line, {column: stripped cell}), read and decoded one line at a time (no decoded copy of the whole
    file). Header names are case-insensitive, may carry a unit (`column_name`) and an alias of `aliases`;
    other columns are ignored.

    Raises a 422 when the file is not UTF-8, holds a NUL character, or its header lacks a required column
    (saying which columns and delimiter it read) or names a wanted one twice, and, while iterating, at a row
    with more non-empty cells than the header has columns (a shifted or merged row must not be read as
    something else) or a cell that cannot be read (`_checked`).
    """
    nul = data.find(b"\x00")
    if nul >= 0:
        line = data.count(b"\n", 0, nul) + 1
        raise csv_error([("", f"CSV line {line}: contains a NUL character, which text may not hold")])
    text = io.TextIOWrapper(io.BytesIO(data), encoding="utf-8-sig", newline="")  # decoded line by line
    try:
        first = text.readline()
    except UnicodeDecodeError as exc:
        raise csv_error([("", f"the file is not UTF-8 text ({exc})")]) from exc
    delimiter = delimiter_of(first)
    reader = _checked(csv.reader(itertools.chain([first], text), delimiter=delimiter))
    header = header_of(next(reader, []), delimiter, aliases)
    missing = [c for c in required if c not in header.names]
    if missing:
        raise csv_error(
            [
                (
                    "",
                    f"CSV line 1: the header must name the columns {', '.join(required)}; missing "
                    f"{', '.join(missing)}; {header.described()}",
                )
            ]
        )
    for c in (*required, *optional):
        named = [header.cells[i] for i, name in enumerate(header.names) if name == c]
        if len(named) > 1:
            raise csv_error(
                [("", f"CSV line 1: the columns {', '.join(map(repr, named))} each name {c}; keep one")]
            )
    col = {c: header.names.index(c) for c in (*required, *optional) if c in header.names}
    width = len(header.cells)

    def rows() -> Iterator[tuple[int, dict[str, str]]]:
        for line, row in enumerate(reader, start=2):
            if any(cell.strip() for cell in row):
                if len(row) > width and any(cell.strip() for cell in row[width:]):
                    raise csv_error(
                        [
                            (
                                "",
                                f"CSV line {line}: has {len(row)} cells but the header names {width} "
                                "columns; remove the extra cells (or quote a cell that contains a "
                                f"{DELIMITERS[delimiter]})",
                            )
                        ]
                    )
                yield line, {c: (row[i].strip() if i < len(row) else "") for c, i in col.items()}

    return CsvTable(header, col, rows())


def csv_rows(
    data: bytes, *, required: Sequence[str], optional: Sequence[str] = ()
) -> tuple[set[str], Iterator[tuple[int, dict[str, str]]]]:
    """(columns present, rows) of a UTF-8 CSV, as `csv_table` reads it."""
    table = csv_table(data, required=required, optional=optional)
    return set(table.columns), table.rows
