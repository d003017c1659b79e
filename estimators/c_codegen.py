"""A fitted compensator as a self-contained C function for the gyro's microprocessor.

Paper 001 (Fig. 4) runs the bias compensation on a microprocessor that receives the temperature,
its slope, U_HFO and the gyro output. :func:`generate_c` turns an
:class:`~rlgsim.estimators.model_export.ExportedCompensator` into a C99 source and header with no
dependency beyond ``<math.h>`` (``exp``, ``pow``) and no allocation::

    double NAME(const double x[NAME_N_INPUTS], unsigned long long *range_flags);

``x`` holds the inputs in the order and units listed in the header (``NAME_INPUT_NAMES``,
``NAME_INPUT_UNITS``); the return value is the predicted target (e.g. the gyro bias in °/h, to
be subtracted from the gyro output). ``range_flags`` may be ``NULL``; otherwise it receives a bit
mask with bit ``i`` set when ``x[i]`` lies outside the training range ``[NAME_TRAIN_MIN[i],
NAME_TRAIN_MAX[i]]`` or is NaN (inputs from the 64th on share bit 63). The value is still
computed, but it is an extrapolation — learnt laws did 2.4 times worse off the training range on
hold-out runs — and the caller decides whether to use it. ``0`` means every input is inside.

Which generator:

* PSO-SVR exported from its fitted model: the kernel sum of the scikit-learn ``SVR`` is emitted
  by **m2cgen** (``m2cgen.export_to_c``), a code generator for scikit-learn models; the input
  standardisation, the target de-standardisation of the ``TransformedTargetRegressor`` around it
  (which m2cgen does not take) and the range check are written around it here.
* Everything else — the polynomial kinds (least squares, stepwise, MLR-BIC), LS-SVM and
  IR-LSSVM, RVR and HHO-RVR, both RBF networks, and a PSO-SVR read back from JSON (no
  scikit-learn object is left for m2cgen to read) — is generated here. m2cgen and emlearn only
  take scikit-learn (and a few other libraries') classes; emlearn has no kernel models and
  m2cgen's nearest classes (linear models, SVR) do not hold these estimators' own scaling,
  term sets or kernel conventions. All of them are a weighted sum of simple terms — monomials
  of the standardised inputs, or Gaussian kernels ``exp(-k·‖z − c_j‖²)`` — so the generator
  is small: constant tables and one loop, which also keeps the code size linear in the number
  of centres (m2cgen writes one expression per support vector).

Numbers are written with Python's ``repr`` (shortest round-trip decimal), which a C compiler
reads back to the same double, so the C function agrees with Python's ``predict`` to rounding of
the arithmetic (tests: 1000 inputs per kind, 1e-9 relative).
"""

from __future__ import annotations

import keyword
import pathlib
import re
from dataclasses import dataclass

import numpy as np

from rlgsim.ground.atomic import atomic_file
from rlgsim.estimators.model_export import ExportedCompensator, export_compensator
from rlgsim.estimators.terms import term_label

__all__ = ["CSource", "c_identifier", "generate_c", "save_compensator", "write_c"]

#: Numbers per line in the constant tables.
_PER_LINE = 4
_ASCII = {"°": "deg", "²": "^2", "³": "^3", "µ": "u", "·": "*", "−": "-", "√": "sqrt",
          "…": "..", "Ω": "Ohm"}


@dataclass(frozen=True)
class CSource:
    """A generated C function: ``function_name``, the ``.c`` text and the ``.h`` text."""

    function_name: str
    c: str
    h: str


def _ascii(text: str) -> str:
    """Comment-safe ASCII: °C → degC, no ``*/``, no control characters."""
    for k, v in _ASCII.items():
        text = text.replace(k, v)
    text = text.encode("ascii", "replace").decode("ascii")
    text = text.replace("*/", "* /").replace("/*", "/ *")
    return re.sub(r"[\x00-\x1f]", " ", text)


def c_identifier(name: str) -> str:
    """A C identifier from a compensator name: ``"LSSVM (T, dT/dt)"`` → ``"lssvm_t_dt_dt"``."""
    ident = re.sub(r"[^0-9a-zA-Z]+", "_", _ascii(name)).strip("_").lower() or "compensator"
    if ident[0].isdigit():
        ident = "c_" + ident
    if keyword.iskeyword(ident) or ident in {"double", "int", "float", "char", "const",
                                             "unsigned", "return", "static", "exp", "pow"}:
        ident += "_model"
    return ident


def _num(v: float) -> str:
    text = repr(float(v))
    if not np.isfinite(v):
        raise ValueError(f"cannot write the non-finite number {v} into C")
    return text if any(c in text for c in ".en") else text + ".0"


def _table(values, indent: str = "    ") -> str:
    flat = [_num(v) for v in np.ravel(values)]
    rows = [", ".join(flat[i:i + _PER_LINE]) for i in range(0, len(flat), _PER_LINE)]
    return (",\n" + indent).join(rows)


def _rows(matrix, indent: str = "    ") -> str:
    """A 2-D table, one braced row per line."""
    return (",\n" + indent).join("{" + ", ".join(_num(v) for v in row) + "}"
                                  for row in np.asarray(matrix))


def _string_table(items) -> str:
    return ", ".join('"' + _ascii(s).replace("\\", "\\\\").replace('"', '\\"') + '"'
                     for s in items)


def _wrap(text: str, width: int = 90) -> list[str]:
    """``text`` split at spaces into lines of at most ``width`` characters."""
    lines, line = [], ""
    for word in _ascii(text).split(" "):
        if line and len(line) + 1 + len(word) > width:
            lines.append(line)
            line = "    " + word
        else:
            line = f"{line} {word}" if line else word
    return lines + [line]


def _monomial(powers) -> str:
    factors = []
    for i, e in enumerate(powers):
        if e == 1:
            factors.append(f"z[{i}]")
        elif e == 2:
            factors.append(f"(z[{i}] * z[{i}])")
        elif e > 2:
            factors.append(f"pow(z[{i}], {e}.0)")
    return " * ".join(factors)


def _m2cgen_core(svr, name: str) -> str:
    """m2cgen's C for the SVR kernel sum, as a static function ``name(double *input)``."""
    import m2cgen
    code = m2cgen.export_to_c(svr, function_name=name)
    code = "\n".join(line for line in code.splitlines() if not line.startswith("#include"))
    code = code.replace(f"double {name}(", f"static double {name}(", 1)
    if f"static double {name}(" not in code:
        raise RuntimeError("unexpected m2cgen output: no function "
                           f"{name!r} found; check the installed m2cgen version")
    return code.strip() + "\n"


def _banner(model: ExportedCompensator, fn: str) -> str:
    """The comment block that opens both files: the compensator, its inputs with units and
    training ranges, its equation in input units (polynomial form) and the flags' meaning."""
    doc = model.document_
    unit = f" [{_ascii(model.target_unit_)}]" if model.target_unit_ else ""
    lines = [f" * {fn}: compensator {_ascii(model.name_)!r} (kind {model.kind_}, form "
             f"{model.form_}),",
             f" * written by rlgsim {doc.get('library_version', '?')}; returns "
             f"{_ascii(model.target_)}{unit}.",
             " * Inputs x[i] (unit; training range):"]
    for i, (nm, u) in enumerate(zip(model.input_names_, model.input_units_)):
        lines.append(f" *   x[{i}] = {_ascii(nm)} ({_ascii(u) or 'no unit given'}; "
                     f"{float(model.train_min_[i])!r} .. {float(model.train_max_[i])!r})")
    if model.form_ == "polynomial":
        lines += [" * In input units (for reading; the code evaluates the standardised form):",
                  *(" *   " + line for line in _wrap(model.raw_equation(ascii=True)))]
    lines += [" * range_flags (may be NULL): bit i set when x[i] is outside its training range",
              " * or NaN; the value is then an extrapolation. 0: every input inside."]
    return "/*\n" + "\n".join(lines) + "\n */\n"


def _header(banner: str, fn: str, n: int) -> str:
    """The ``.h`` file: include guard, input count, the tables' and the function's
    declarations."""
    up = fn.upper()
    guard = f"{up}_H"
    return (f"{banner}#ifndef {guard}\n#define {guard}\n\n"
            f"#define {up}_N_INPUTS {n}\n\n"
            f"/* input names and units, in the order of x */\n"
            f"extern const char *const {up}_INPUT_NAMES[{up}_N_INPUTS];\n"
            f"extern const char *const {up}_INPUT_UNITS[{up}_N_INPUTS];\n"
            f"extern const double {up}_TRAIN_MIN[{up}_N_INPUTS];\n"
            f"extern const double {up}_TRAIN_MAX[{up}_N_INPUTS];\n\n"
            f"double {fn}(const double x[{up}_N_INPUTS], unsigned long long *range_flags);\n\n"
            f"#endif /* {guard} */\n")


def _tables(model: ExportedCompensator, banner: str, fn: str, use_m2cgen: bool) -> list[str]:
    """The ``.c`` file's blocks before the function: includes, the input tables, the
    standardisation and the form's constants (polynomial coefficients, the m2cgen kernel sum,
    or the Gaussian kernel's centres and output scaling)."""
    up = fn.upper()
    body = [f"{banner}#include <math.h>\n#include <stddef.h>\n\n#include \"{fn}.h\"\n",
            f"const char *const {up}_INPUT_NAMES[{up}_N_INPUTS] = "
            f"{{{_string_table(model.input_names_)}}};",
            f"const char *const {up}_INPUT_UNITS[{up}_N_INPUTS] = "
            f"{{{_string_table(model.input_units_)}}};",
            f"const double {up}_TRAIN_MIN[{up}_N_INPUTS] = {{\n    {_table(model.train_min_)}}};",
            f"const double {up}_TRAIN_MAX[{up}_N_INPUTS] = {{\n    {_table(model.train_max_)}}};",
            "/* standardised inputs z[i] = (x[i] - CENTER[i]) / SCALE[i] */\n"
            f"static const double {up}_CENTER[{up}_N_INPUTS] = {{\n    {_table(model.center_)}}};",
            f"static const double {up}_SCALE[{up}_N_INPUTS] = {{\n    {_table(model.scale_)}}};"]
    if model.form_ == "polynomial":
        k = len(model.powers_)
        coef = (f"\nstatic const double {up}_COEF[{k}] = {{\n    {_table(model.coef_)}}};"
                if k else "")
        body.append(f"/* y = INTERCEPT + sum_k COEF[k] * term_k(z) */\n"
                    f"static const double {up}_INTERCEPT = {_num(model.intercept_)};{coef}")
    elif use_m2cgen:
        body.append("/* kernel sum of the SVR in the standardised inputs (generated by m2cgen) */")
        body.append(_m2cgen_core(model._svr, f"{fn}_svr"))
    elif model.coef_.size == 0:
        body.append(f"/* no centre was kept: y = OUTPUT_OFFSET + OUTPUT_SCALE * INTERCEPT */\n"
                    f"static const double {up}_INTERCEPT = {_num(model.intercept_)};")
    else:
        m = model.coef_.size
        body.append(f"/* y = OUTPUT_OFFSET + OUTPUT_SCALE * (INTERCEPT + sum_j COEF[j] *\n"
                    f"       exp(-KERNEL_FACTOR * |z - CENTRES[j]|^2)) */\n"
                    f"#define {up}_N_CENTRES {m}\n"
                    f"static const double {up}_KERNEL_FACTOR = {_num(model.kernel_factor_)};\n"
                    f"static const double {up}_INTERCEPT = {_num(model.intercept_)};\n"
                    f"static const double {up}_COEF[{up}_N_CENTRES] = {{\n"
                    f"    {_table(model.coef_)}}};\n"
                    f"static const double {up}_CENTRES[{up}_N_CENTRES][{up}_N_INPUTS] = {{\n"
                    f"    {_rows(model.centres_)}}};")
    if model.form_ == "gaussian_kernel":
        body.append(f"static const double {up}_OUTPUT_OFFSET = {_num(model.output_offset_)};\n"
                    f"static const double {up}_OUTPUT_SCALE = {_num(model.output_scale_)};")
    return body


def _function(model: ExportedCompensator, fn: str, use_m2cgen: bool) -> list[str]:
    """The lines of the C function: range flags and standardisation, then the form's sum."""
    up = fn.upper()
    fbody = [f"double {fn}(const double x[{up}_N_INPUTS], unsigned long long *range_flags)", "{",
             f"    double z[{up}_N_INPUTS];", "    double y;", "    unsigned long long flags = 0u;",
             "    int i;"]
    constant = model.coef_.size == 0 and not use_m2cgen    # no term or centre was kept
    if model.form_ == "gaussian_kernel" and not use_m2cgen and not constant:
        fbody.append("    int j;")
    fbody += [f"    for (i = 0; i < {up}_N_INPUTS; ++i) {{",
              f"        if (!(x[i] >= {up}_TRAIN_MIN[i] && x[i] <= {up}_TRAIN_MAX[i])) {{",
              "            flags |= 1ull << (i < 63 ? i : 63);", "        }",
              f"        z[i] = (x[i] - {up}_CENTER[i]) / {up}_SCALE[i];", "    }",
              "    if (range_flags != NULL) {", "        *range_flags = flags;", "    }"]
    if constant:
        fbody.append("    (void)z;  /* the model is a constant */")
    if model.form_ == "polynomial":
        names = [f"z_{nm}" for nm in model.input_names_]
        fbody.append("    y = 0.0;")
        for k, p in enumerate(model.powers_):
            fbody.append(f"    y += {up}_COEF[{k}] * {_monomial(p)};"
                         f"  /* {_ascii(term_label(p, names))} */")
        fbody.append(f"    y += {up}_INTERCEPT;")
    elif use_m2cgen:
        fbody.append(f"    y = {fn}_svr(z);")
        fbody.append(f"    y = y * {up}_OUTPUT_SCALE + {up}_OUTPUT_OFFSET;")
    elif constant:
        fbody += [f"    y = {up}_INTERCEPT;",
                  f"    y = y * {up}_OUTPUT_SCALE + {up}_OUTPUT_OFFSET;"]
    else:
        fbody += ["    y = 0.0;",
                  f"    for (j = 0; j < {up}_N_CENTRES; ++j) {{",
                  "        double d2 = 0.0;",
                  f"        for (i = 0; i < {up}_N_INPUTS; ++i) {{",
                  f"            double d = z[i] - {up}_CENTRES[j][i];",
                  "            d2 += d * d;", "        }",
                  f"        y += {up}_COEF[j] * exp(d2 * -{up}_KERNEL_FACTOR);", "    }",
                  f"    y += {up}_INTERCEPT;",
                  f"    y = y * {up}_OUTPUT_SCALE + {up}_OUTPUT_OFFSET;"]
    return fbody + ["    return y;", "}"]


def generate_c(model: ExportedCompensator, function_name: str | None = None) -> CSource:
    """C source and header of an exported compensator (module docstring for the interface)."""
    fn = c_identifier(function_name or model.name_)
    banner = _banner(model, fn)
    use_m2cgen = model._svr is not None
    body = _tables(model, banner, fn, use_m2cgen)
    c = "\n\n".join(body) + "\n\n" + "\n".join(_function(model, fn, use_m2cgen)) + "\n"
    return CSource(fn, c, _header(banner, fn, len(model.input_names_)))


def write_c(model: ExportedCompensator, directory: str | pathlib.Path,
            function_name: str | None = None) -> tuple[pathlib.Path, pathlib.Path]:
    """Write ``<function_name>.c`` and ``.h`` into ``directory``; returns both paths."""
    src = generate_c(model, function_name)
    directory = pathlib.Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    c_path, h_path = directory / f"{src.function_name}.c", directory / f"{src.function_name}.h"
    for path, text in ((c_path, src.c), (h_path, src.h)):
        with atomic_file(path) as tmp:                  # whole or not at all
            tmp.write_text(text, encoding="ascii")
    return c_path, h_path


def save_compensator(model, X_train, directory: str | pathlib.Path, *, name: str,
                     stem: str | None = None, **metadata) -> dict[str, pathlib.Path]:
    """Export a fitted compensator into ``directory`` as ``<stem>.json``, ``<stem>.c`` and
    ``<stem>.h`` (``stem`` default: a C identifier made from ``name``, also the C function's
    name); returns ``{"json": ..., "c": ..., "h": ...}``. ``metadata``: the keyword arguments
    of :func:`~rlgsim.estimators.model_export.export_compensator` (``input_units``,
    ``target``, ``target_unit`` ...)."""
    exported = export_compensator(model, X_train, name=name, **metadata)
    stem = c_identifier(stem or name)
    c_path, h_path = write_c(exported, directory, stem)
    return {"json": exported.to_json(pathlib.Path(directory) / f"{stem}.json"), "c": c_path,
            "h": h_path}
