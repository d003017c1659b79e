"""Report folders: Markdown, a self-contained HTML page, CSV tables and PNG figures.

A :class:`Report` collects headings, paragraphs, tables, figures and verbatim text in order and
writes them to a folder as ``report.md`` (figures linked as PNG files), ``report.html`` (the
same content with every figure embedded as a base64 data URI, so the page can be mailed or
archived alone) and one CSV file per table. Both studies and Monte Carlo campaigns use it.

Written by hand because the job is small and specific: a Markdown/HTML templating library would
add a dependency without removing much code. Every file is written to a temporary name and
renamed into place, so a crash never leaves a half-written report.
"""

from __future__ import annotations

import base64
import csv
import html
import io
import math
import os
import pathlib
import re
from dataclasses import dataclass, field
from typing import Any, Iterable, Sequence

from rlgsim.ground.atomic import atomic_file
from rlgsim.ground.provenance import versions_line


def write_atomic(path: pathlib.Path, data: bytes | str) -> None:
    """Write ``data`` to ``path`` whole or not at all (:func:`rlgsim.ground.atomic.atomic_file`;
    the temporary file is ``.<name>.tmp<pid>``)."""
    with atomic_file(path, sep="") as tmp:
        if isinstance(data, bytes):
            tmp.write_bytes(data)
        else:
            with open(tmp, "w", encoding="utf-8", newline="") as fh:
                fh.write(data)


def output_folder(path: str | os.PathLike) -> pathlib.Path:
    """Create (if needed) and return a report/output folder; a folder that cannot be created
    is a :class:`~rlgsim.ground.errors.UserInputError` naming it."""
    from rlgsim.ground.errors import UserInputError
    folder = pathlib.Path(path)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserInputError(f"{folder}: cannot create the output folder "
                             f"({exc.strerror or exc})") from None
    return folder


def format_value(value: Any, digits: int = 4) -> str:
    """Human formatting for report cells: ``digits`` significant figures, '—' for missing."""
    if value is None:
        return "—"
    if isinstance(value, (bool, str)):
        return str(value)
    try:
        x = float(value)
    except (TypeError, ValueError):
        return str(value)
    if math.isnan(x):
        return "—"
    if x == int(x) and abs(x) < 1e6 and isinstance(value, (int,)):
        return str(int(x))
    return f"{x:.{digits}g}"


def slug(text: str) -> str:
    """A file-name-safe version of ``text``; a minus sign before a digit becomes "m", so that
    "-40 °C" and "40 °C" stay apart ("m40_c", "40_c")."""
    text = re.sub(r"(?:(?<=^)|(?<=[^A-Za-z0-9]))[-−](?=\d)", "m", text)
    return re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_").lower() or "item"


@dataclass
class Table:
    """A table: column names and rows (sequences of cells). ``csv_name`` names its CSV file."""

    title: str
    columns: list[str]
    rows: list[list[Any]]
    note: str = ""
    csv_name: str = ""

    def __post_init__(self) -> None:
        if not self.csv_name:
            self.csv_name = f"{slug(self.title)}.csv"
        for row in self.rows:
            if len(row) != len(self.columns):
                raise ValueError(f"table {self.title!r}: row {row!r} has {len(row)} cells, "
                                 f"expected {len(self.columns)}")

    @classmethod
    def from_records(cls, title: str, records: Sequence[dict[str, Any]], **kw: Any) -> "Table":
        """Build from a list of dicts (columns in first-seen order)."""
        columns: list[str] = []
        for rec in records:
            for key in rec:
                if key not in columns:
                    columns.append(key)
        rows = [[rec.get(c) for c in columns] for rec in records]
        return cls(title, columns, rows, **kw)

    def csv_text(self) -> str:
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(self.columns)
        for row in self.rows:
            # repr of the Python float: the shortest text that reads back to the same double
            # (NumPy's float64 is a float whose own repr is "np.float64(...)" since NumPy 2)
            writer.writerow(["" if v is None else (repr(float(v)) if isinstance(v, float)
                                                   else v) for v in row])
        return buf.getvalue()

    def markdown(self, digits: int = 4) -> str:
        def cell(v: Any) -> str:
            return format_value(v, digits).replace("|", "\\|")
        lines = ["| " + " | ".join(self.columns) + " |",
                 "|" + "|".join("---" for _ in self.columns) + "|"]
        lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in self.rows]
        return "\n".join(lines)

    def html(self, digits: int = 4) -> str:
        head = "".join(f"<th>{html.escape(c)}</th>" for c in self.columns)
        body = "".join(
            "<tr>" + "".join(f"<td>{html.escape(format_value(v, digits))}</td>" for v in row)
            + "</tr>" for row in self.rows)
        return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


@dataclass
class _Item:
    kind: str
    payload: Any
    extra: dict[str, Any] = field(default_factory=dict)


class Report:
    """An ordered report. Add content, then :meth:`write` it to a folder."""

    def __init__(self, title: str) -> None:
        self.title = title
        self._items: list[_Item] = []
        self._figure_names: set[str] = set()

    # -- content ---------------------------------------------------------------------------
    def heading(self, text: str, level: int = 2) -> None:
        self._items.append(_Item("heading", text, {"level": level}))

    def paragraph(self, text: str) -> None:
        self._items.append(_Item("paragraph", text))

    def bullets(self, items: Iterable[str]) -> None:
        self._items.append(_Item("bullets", list(items)))

    def table(self, table: Table) -> Table:
        self._items.append(_Item("table", table))
        return table

    def attachment(self, table: Table) -> Table:
        """A table too long to show (e.g. a time series): written as CSV, linked from the
        report with its title, note and size."""
        self._items.append(_Item("attachment", table))
        return table

    def figure(self, fig: Any, name: str, caption: str = "") -> str:
        """Add a matplotlib figure; it is rendered to PNG now and closed. Returns its file name."""
        import matplotlib.pyplot as plt

        base = slug(name)
        fname, n = f"{base}.png", 1
        while fname in self._figure_names:
            n += 1
            fname = f"{base}_{n}.png"
        self._figure_names.add(fname)
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
        plt.close(fig)
        self._items.append(_Item("figure", buf.getvalue(), {"name": fname, "caption": caption}))
        return fname

    def verbatim(self, text: str, title: str = "", language: str = "") -> None:
        self._items.append(_Item("verbatim", text, {"title": title, "language": language}))

    @property
    def tables(self) -> list[Table]:
        return [item.payload for item in self._items if item.kind in ("table", "attachment")]

    # -- output ----------------------------------------------------------------------------
    def markdown(self) -> str:
        out = [f"# {self.title}", ""]
        for item in self._items:
            if item.kind == "heading":
                out += ["#" * item.extra["level"] + " " + item.payload, ""]
            elif item.kind == "paragraph":
                out += [item.payload, ""]
            elif item.kind == "bullets":
                out += [f"- {b}" for b in item.payload] + [""]
            elif item.kind == "table":
                t: Table = item.payload
                out += [f"**{t.title}** ([CSV]({t.csv_name}))", "", t.markdown(), ""]
                if t.note:
                    out += [f"*{t.note}*", ""]
            elif item.kind == "attachment":
                t = item.payload
                out += [f"**{t.title}**: [{t.csv_name}]({t.csv_name}), {len(t.rows)} rows × "
                        f"{len(t.columns)} columns ({', '.join(t.columns)})"
                        + (f". *{t.note}*" if t.note else ""), ""]
            elif item.kind == "figure":
                cap = item.extra["caption"]
                out += [f"![{cap or item.extra['name']}]({item.extra['name']})", ""]
                if cap:
                    out += [f"*{cap}*", ""]
            elif item.kind == "verbatim":
                if item.extra["title"]:
                    out += [f"**{item.extra['title']}**", ""]
                out += [f"```{item.extra['language']}", item.payload.rstrip("\n"), "```", ""]
        out += ["---", "", f"*Made with {versions_line()}.*", ""]
        return "\n".join(out)

    def html(self) -> str:
        body = [f"<h1>{html.escape(self.title)}</h1>"]
        for item in self._items:
            if item.kind == "heading":
                lvl = min(6, item.extra["level"])
                body.append(f"<h{lvl}>{html.escape(item.payload)}</h{lvl}>")
            elif item.kind == "paragraph":
                body.append(f"<p>{html.escape(item.payload)}</p>")
            elif item.kind == "bullets":
                body.append("<ul>" + "".join(f"<li>{html.escape(b)}</li>" for b in item.payload)
                            + "</ul>")
            elif item.kind == "table":
                t = item.payload
                body.append(f"<h4>{html.escape(t.title)}</h4><div class='table-wrap'>"
                            + t.html() + "</div>")
                if t.note:
                    body.append(f"<p class='note'>{html.escape(t.note)}</p>")
            elif item.kind == "attachment":
                t = item.payload
                body.append(f"<p><b>{html.escape(t.title)}</b>: <a href='{html.escape(t.csv_name)}'>"
                            f"{html.escape(t.csv_name)}</a>, {len(t.rows)} rows × "
                            f"{len(t.columns)} columns ({html.escape(', '.join(t.columns))})"
                            + (f". <i>{html.escape(t.note)}</i>" if t.note else "") + "</p>")
            elif item.kind == "figure":
                data = base64.b64encode(item.payload).decode("ascii")
                cap = html.escape(item.extra["caption"])
                body.append(f"<figure><img alt='{html.escape(item.extra['name'])}' "
                            f"src='data:image/png;base64,{data}'><figcaption>{cap}</figcaption>"
                            "</figure>")
            elif item.kind == "verbatim":
                if item.extra["title"]:
                    body.append(f"<h4>{html.escape(item.extra['title'])}</h4>")
                body.append(f"<pre>{html.escape(item.payload)}</pre>")
        # the page takes the window's width (up to 1900 px) so tables and figures are not
        # squeezed into a text column; prose keeps a readable measure; a table's cells wrap
        # (long names anywhere) before its box scrolls; figures at their own size
        style = ("body{font-family:sans-serif;max-width:1900px;margin:2em auto;padding:0 1.5em;"
                 "color:#222}p,ul,ol,h1,h2,h3,h4,figcaption{max-width:80em}"
                 "table{border-collapse:collapse;margin:.5em 0 1.5em;font-size:.92em}"
                 "th,td{border:1px solid #bbb;padding:.2em .45em;text-align:right;"
                 "max-width:16em;overflow-wrap:anywhere}"
                 ".table-wrap{max-width:100%;overflow-x:auto}"   # a wide table scrolls inside
                 "th{background:#eee}figure{margin:1em 0}img{max-width:100%;height:auto}"
                 "pre{background:#f6f6f6;padding:.8em;overflow-x:auto}.note{font-style:italic}")
        body.append(f"<hr><p class='note'>Made with {html.escape(versions_line())}.</p>")
        return ("<!DOCTYPE html><html><head><meta charset='utf-8'>"
                f"<title>{html.escape(self.title)}</title><style>{style}</style></head><body>"
                + "\n".join(body) + "</body></html>")

    def write(self, folder: str | os.PathLike) -> pathlib.Path:
        """Write report.md, report.html, every table as CSV and every figure as PNG."""
        folder = pathlib.Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        for item in self._items:
            if item.kind == "figure":
                write_atomic(folder / item.extra["name"], item.payload)
            elif item.kind in ("table", "attachment"):
                write_atomic(folder / item.payload.csv_name, item.payload.csv_text())
        write_atomic(folder / "report.md", self.markdown())
        write_atomic(folder / "report.html", self.html())
        return folder / "report.md"
