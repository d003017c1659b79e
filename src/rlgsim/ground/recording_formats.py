"""The table formats a recording may be: the one registry the reader
(:mod:`rlgsim.ground.recording`), the exporter (:mod:`rlgsim.ground.recording_export`) and the
``rlgsim export`` command take their lists from.

A recording is a table file with a TOML sidecar (docs/recordings.md). Each format has a name
(what ``rlgsim export --format`` and the sidecar's reader call it), the file suffixes it is
recognised by (the first is the one the exporter writes) and whether the exporter writes it.

To add a format: one line here, its reader in ``recording_read._read_table`` and, when the exporter
writes it, its writer in ``recording_write.write_table``.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["TableFormat", "TABLE_FORMATS", "DATA_SUFFIXES", "EXPORT_FORMATS"]


@dataclass(frozen=True)
class TableFormat:
    """One table format of a recording."""

    suffixes: tuple[str, ...]       # lower case, the written one first
    exported: bool                  # ``rlgsim export`` writes it


#: format name → its suffixes and whether the exporter writes it.
TABLE_FORMATS: dict[str, TableFormat] = {
    "csv": TableFormat((".csv",), exported=True),
    "parquet": TableFormat((".parquet", ".pq"), exported=True),
    "hdf5": TableFormat((".h5", ".hdf5", ".hdf"), exported=False),     # another tool's table
}

#: Table files a recording may be: suffix → format name.
DATA_SUFFIXES: dict[str, str] = {s: name for name, f in TABLE_FORMATS.items() for s in f.suffixes}
#: The formats the exporter writes: name → the suffix it writes.
EXPORT_FORMATS: dict[str, str] = {name: f.suffixes[0] for name, f in TABLE_FORMATS.items()
                                  if f.exported}
