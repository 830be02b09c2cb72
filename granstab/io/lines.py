"""Numeric text tables read in one vectorised call (numpy.loadtxt), with one-line errors naming the file, the
line and the field. The per-line scan below runs only after loadtxt has failed, to say where."""
from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np

from ..model.errors import SceneError

WINDOW_BUFFER = 1 << 20   # bytes read at a time from a block of rows


def read_table(path, fields, *, delimiter=None, comments="#", skiprows=0, min_rows=0, progress=None) -> np.ndarray:
    """Rows of numbers with `len(fields)` columns or more, as a float (rows, columns) array; `progress(n_bytes)` is
    called as the file is read.

    `fields` names the leading columns (for messages); extra columns are kept. Raises SceneError
    "<file>: line L: <field>: <problem>" for a missing file, a non-number, a short row or a non-finite value."""
    path = Path(path)
    try:
        with warnings.catch_warnings():  # an empty table is reported below, as one line
            warnings.simplefilter("ignore", UserWarning)
            if progress is None:
                data = np.loadtxt(path, delimiter=delimiter, comments=comments, skiprows=skiprows, ndmin=2)
            else:
                with _window(path, 0, path.stat().st_size, progress) as lines:
                    data = np.loadtxt(lines, delimiter=delimiter, comments=comments, skiprows=skiprows, ndmin=2)
    except OSError as exc:
        raise SceneError(f"{path}: cannot read file ({exc.strerror or exc})") from None
    except (ValueError, UnicodeDecodeError):
        _raise_first_bad_line(path, fields, delimiter, comments, skiprows)
    if data.size == 0:
        if min_rows:
            raise SceneError(f"{path}: no data rows")
        return np.zeros((0, len(fields)))
    if data.shape[0] < min_rows:
        raise SceneError(f"{path}: {data.shape[0]} data rows, expected at least {min_rows}")
    if data.size and data.shape[1] < len(fields):
        raise SceneError(f"{path}: line {_data_lines(path, comments, skiprows)[0]}: {fields[data.shape[1]]}: "
                         f"missing column ({data.shape[1]} columns, expected {len(fields)}: {', '.join(fields)})")
    bad = ~np.isfinite(data)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        line = _data_lines(path, comments, skiprows)[row]
        raise SceneError(f"{path}: line {line}: {column_name(fields, col)}: not a finite number ({data[row, col]})")
    return data


def is_number(text) -> bool:
    """Whether float() reads `text` (the first cell that is not a number, for a one-line error)."""
    try:
        float(text)
    except (TypeError, ValueError):
        return False
    return True


def column_name(fields, col: int) -> str:
    return fields[col] if col < len(fields) else f"column {col + 1}"


def _data_lines(path: Path, comments, skiprows) -> list[int]:
    """1-based file line numbers of the data rows (error path only)."""
    lines = []
    with open(path, encoding="utf-8", errors="replace") as fh:
        for number, text in enumerate(fh, 1):
            if number <= skiprows:
                continue
            if comments:
                text = text.split(comments, 1)[0]
            if text.strip():
                lines.append(number)
    return lines


def _raise_first_bad_line(path: Path, fields, delimiter, comments, skiprows):
    with open(path, encoding="utf-8", errors="replace") as fh:
        numbered = ((number, text) for number, text in enumerate(fh, 1) if number > skiprows)
        scan_rows(numbered, path, fields, delimiter, comments)
    raise SceneError(f"{path}: not a numeric table")


def scan_rows(numbered, path, fields, delimiter=None, comments="#"):
    """Find the first line that is not a row of numbers as wide as the first one; raise its one-line error."""
    width = None
    for number, text in numbered:
        if comments:
            text = text.split(comments, 1)[0]
        if not text.strip():
            continue
        cells = [c.strip() for c in text.split(delimiter)]
        for col, cell in enumerate(cells):
            try:
                float(cell)
            except ValueError:
                raise SceneError(f"{path}: line {number}: {column_name(fields, col)}: not a number "
                                 f"({cell[:40]!r})") from None
        if width is None:
            width = len(cells)
            if width < len(fields):
                raise SceneError(f"{path}: line {number}: {fields[width]}: missing column ({width} columns, "
                                 f"expected {len(fields)}: {', '.join(fields)})")
        elif len(cells) != width:
            name = column_name(fields, min(len(cells), width))
            raise SceneError(f"{path}: line {number}: {name}: {len(cells)} columns where the lines before have "
                             f"{width} (truncated or garbled line?)")


def read_block(text: str, first_line: int, path, fields, rows: int, what: str) -> np.ndarray:
    """A block of `rows` whitespace-separated rows of len(fields) numbers starting at file line `first_line`
    (a dump's ATOMS/ENTRIES section), with one-line errors naming the line and field."""
    try:
        data = _loadtxt(io.StringIO(text))
    except ValueError:
        scan_rows(enumerate(text.splitlines(), first_line), path, fields, comments=None)
        raise SceneError(f"{path}: line {first_line}: {what}: not a numeric table") from None
    return _check_block(data, first_line, path, fields, rows, what)


def read_window(path, start: int, end: int, first_line: int, fields, rows: int, what: str,
                progress=None) -> np.ndarray:
    """`read_block` of the bytes [start, end) of a file (a dump's ATOMS/ENTRIES rows), parsed by numpy.loadtxt
    straight from the file: memory is that of the rows of this block, not of the file. `progress(n_bytes)` is
    called as the bytes are read."""
    try:
        with _window(path, start, end, progress) as lines:
            data = _loadtxt(lines)
    except OSError as exc:
        raise SceneError(f"{path}: cannot read file ({exc.strerror or exc})") from None
    except ValueError:
        with _window(path, start, end) as lines:
            scan_rows(enumerate(lines, first_line), path, fields, comments=None)
        raise SceneError(f"{path}: line {first_line}: {what}: not a numeric table") from None
    return _check_block(data, first_line, path, fields, rows, what)


def _loadtxt(lines) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return np.loadtxt(lines, ndmin=2, comments=None)


def _check_block(data: np.ndarray, first_line: int, path, fields, rows: int, what: str) -> np.ndarray:
    if data.shape[0] != rows:
        raise SceneError(f"{path}: line {first_line + data.shape[0]}: {what}: {data.shape[0]} rows where the header "
                         f"says {rows} (truncated file?)")
    if rows and data.shape[1] != len(fields):
        raise SceneError(f"{path}: line {first_line}: {column_name(fields, min(data.shape[1], len(fields)))}: "
                         f"{data.shape[1]} columns where the header names {len(fields)}")
    bad = ~np.isfinite(data)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise SceneError(f"{path}: line {first_line + row}: {column_name(fields, col)}: not a finite number "
                         f"({data[row, col]})")
    return data


class _Bytes(io.RawIOBase):
    """The bytes [start, end) of a file as a raw stream (what a dump block's rows are), reporting progress."""

    def __init__(self, path, start: int, end: int, progress=None):
        self.fh = open(path, "rb", buffering=0)
        self.fh.seek(start)
        self.left, self.progress = end - start, progress

    def readable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        view = memoryview(buffer)[:max(0, min(len(buffer), self.left))]
        n = self.fh.readinto(view) if len(view) else 0
        self.left -= n
        if self.progress is not None and n:
            self.progress(n)
        return n

    def close(self) -> None:
        self.fh.close()
        super().close()


def _window(path, start: int, end: int, progress=None) -> io.TextIOWrapper:
    """Text lines of the bytes [start, end) of `path` (universal newlines, undecodable bytes replaced)."""
    return io.TextIOWrapper(io.BufferedReader(_Bytes(path, start, end, progress), WINDOW_BUFFER), encoding="utf-8",
                            errors="replace")


def line_of(path, row: int, comments="#", skiprows=0) -> int:
    """1-based file line of data row `row` (for error messages; scans the file)."""
    return _data_lines(Path(path), comments, skiprows)[row]


def pick_frame(values: np.ndarray, frame, source, what="frame"):
    """The frame to read (default: the first) and the sorted list of frames in `values`."""
    frames = np.unique(values)
    if frames.size == 0:
        raise SceneError(f"{source}: no data rows")
    if frame is None:
        return frames[0], frames
    if not np.any(frames == frame):
        shown = ", ".join(f"{v:g}" for v in frames[:5]) + (", …" if frames.size > 5 else "")
        raise SceneError(f"{source}: {what} {frame}: {what}: not in the file (it has {frames.size}: {shown})")
    return frames[frames == frame][0], frames


def integer_column(values: np.ndarray, path, field: str, rows=None) -> np.ndarray:
    """Integer ids from a float column; a fractional value is a one-line error naming its line."""
    ints = np.rint(values).astype(np.int64)
    bad = np.flatnonzero(ints != values)
    if bad.size:
        row = bad[0] if rows is None else rows[bad[0]]
        raise SceneError(f"{path}: line {line_of(path, row)}: {field}: not an integer ({values[bad[0]]})")
    return ints


def check_unique(ids: np.ndarray, path, field: str, rows=None) -> None:
    """Particle ids of one frame are unique; the second listing is a one-line error naming its line."""
    order = np.argsort(ids, kind="stable")
    same = np.flatnonzero(ids[order][1:] == ids[order][:-1])
    if same.size:
        second = order[same[0] + 1]
        row = second if rows is None else rows[second]
        raise SceneError(f"{path}: line {line_of(path, row)}: {field}: {ids[second]} listed twice in one frame")
