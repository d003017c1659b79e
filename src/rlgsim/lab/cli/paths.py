"""The command line's path checks: :mod:`rlgsim.ground.paths` (shared with the API functions
that write files); imported here under the name the commands use."""

from __future__ import annotations

from rlgsim.ground.paths import (MAX_NAME, check_writable, file_kind, input_file, name_path,
                                 output_file, output_files, output_folder, sweep_temporaries)

__all__ = ["MAX_NAME", "check_writable", "file_kind", "input_file", "name_path", "output_file",
           "output_files", "output_folder", "sweep_temporaries"]
