"""Polynomial terms of named inputs: enumeration, labels, parsing, design matrices, equations.

Shared by the least-squares polynomial, MLR with BIC selection and stepwise regression.  A term
is a tuple of non-negative exponents, one per input: with inputs ``(T, dT/dt)`` the term
``(1, 1)`` is ``T·dT/dt`` and ``(2, 0)`` is ``T²``; the constant ``(0, 0)`` is the intercept
and is never listed as a term.

Conditioning: the estimators evaluate terms on *scaled* inputs ``z = (x − c)/s`` and convert
the fitted coefficients back to raw-unit coefficients only for reporting
(:func:`raw_coefficients`, an exact binomial expansion).  With ``c = 0`` (pure scaling) each
raw term maps to one scaled term, so subset selection over terms is unchanged by the scaling;
a shift ``c ≠ 0`` is used only when every lower-order term is in the model (full polynomial).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from itertools import product

import numpy as np
from sklearn.preprocessing import PolynomialFeatures

Powers = tuple[int, ...]

_SUPERSCRIPT = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")
_FROM_SUPERSCRIPT = {v: k for k, v in zip("0123456789", "⁰¹²³⁴⁵⁶⁷⁸⁹")}


def polynomial_powers(n_features: int, degree: int, interaction: bool = True) -> list[Powers]:
    """All non-constant terms up to total ``degree``, ordered by degree (sklearn's order).

    ``interaction=False`` keeps only pure powers of single inputs (no cross terms).
    Uses ``sklearn.preprocessing.PolynomialFeatures`` to enumerate the exponents.
    """
    if not isinstance(degree, (int, np.integer)) or isinstance(degree, bool) or degree < 1:
        raise ValueError(f"degree must be an integer >= 1, got {degree!r}")
    powers = PolynomialFeatures(degree, include_bias=False).fit(
        np.zeros((1, n_features))).powers_
    out = [tuple(int(p) for p in row) for row in powers]
    if not interaction:
        out = [p for p in out if sum(1 for e in p if e) == 1]
    return out


def term_label(powers: Powers, names: Sequence[str]) -> str:
    """Plain-text label: ``"T"``, ``"T^2"``, ``"T*dT/dt"`` (parseable by :func:`parse_term`)."""
    parts = [n if e == 1 else f"{n}^{e}" for n, e in zip(names, powers) if e]
    return "*".join(parts) if parts else "1"


def term_pretty(powers: Powers, names: Sequence[str]) -> str:
    """Display label as in the papers: ``"T²"``, ``"(dT/dt)²"``, ``"T·dT/dt"``.

    A name that would read as arithmetic (``"A-B"``, a probe-pair gradient) is parenthesised:
    ``"(A-B)"``; any other non-word name only when raised to a power.
    """
    parts = []
    for n, e in zip(names, powers):
        if not e:
            continue
        if re.search(r"[-+*·\s]", n) or (e > 1 and re.search(r"[^\w.]", n)):
            n = f"({n})"
        parts.append(n if e == 1 else n + str(e).translate(_SUPERSCRIPT))
    return "·".join(parts) if parts else "1"


def parse_term(term: str | Sequence[int], names: Sequence[str]) -> Powers:
    """Exponent tuple of ``term``: an exponent sequence or a label such as ``"T^2"``,
    ``"T²"``, ``"(dT/dt)^2"``, ``"T*dT/dt"``, ``"T·U"``.

    Raises ``ValueError`` naming the term and the known inputs if it cannot be read.
    """
    n = len(names)
    if not isinstance(term, str):
        powers = tuple(int(e) for e in term)
        if len(powers) != n or min(powers) < 0 or sum(powers) == 0:
            raise ValueError(f"term {tuple(term)} must be {n} non-negative exponents, not all 0")
        return powers
    index = {name: i for i, name in enumerate(names)}
    exps = [0] * n
    factors = [term] if term in index else re.split(r"\s*[*·]\s*", term.strip())
    for factor in factors:
        base, exp = factor, 1
        if factor not in index and factor.startswith("(") and factor.endswith(")") \
                and factor[1:-1] in index:
            base = factor[1:-1]
        elif factor not in index:
            m = re.fullmatch(r"(.+?)\^(\d+)", factor) or re.fullmatch(r"(.+?)([⁰¹²³⁴⁵⁶⁷⁸⁹]+)",
                                                                      factor)
            if m:
                base = m.group(1)
                exp = int("".join(_FROM_SUPERSCRIPT.get(c, c) for c in m.group(2)))
                if base not in index and base.startswith("(") and base.endswith(")"):
                    base = base[1:-1]
        if base not in index or exp < 1:
            raise ValueError(f"cannot read term {term!r}: {factor!r} is not one of the inputs "
                             f"({', '.join(names)}) optionally raised to a power")
        exps[index[base]] += exp
    return tuple(exps)


def design_matrix(Z: np.ndarray, powers: Sequence[Powers]) -> np.ndarray:
    """Columns ``Π_i Z[:, i]**p_i`` for each term (no constant column); shape (n, len(powers))."""
    out = np.ones((Z.shape[0], len(powers)))
    for j, p in enumerate(powers):
        for i, e in enumerate(p):
            if e:
                out[:, j] *= Z[:, i] ** e
    return out


def raw_coefficients(powers: Sequence[Powers], coef_z: np.ndarray, intercept_z: float,
                     center: np.ndarray, scale: np.ndarray) -> dict[Powers, float]:
    """Coefficients on raw-unit monomials of a polynomial fitted on ``z = (x − center)/scale``.

    Exact binomial expansion of ``Π_i ((x_i − c_i)/s_i)^{p_i}``; returns ``{powers: coef}``
    including the constant ``(0, ..., 0)``.  Raw coefficients of high-degree fits on shifted
    data can be large and cancelling; they are for reporting, predictions use the scaled form.
    """
    n = len(center)
    out: dict[Powers, float] = {(0,) * n: float(intercept_z)}
    for p, b in zip(powers, coef_z):
        # per input: list of (exponent k, factor) from (x - c)^e / s^e
        per_input = [[(k, math.comb(e, k) * (-center[i]) ** (e - k) / scale[i] ** e)
                      for k in range(e + 1) if center[i] != 0 or k == e]
                     for i, e in enumerate(p)]
        for combo in product(*per_input):
            key = tuple(k for k, _ in combo)
            out[key] = out.get(key, 0.0) + float(b) * math.prod(f for _, f in combo)
    return out


def format_number(value: float, precision: int = 4, ascii: bool = False) -> str:
    """``value`` to ``precision`` significant digits; ``1.427×10⁻³`` unless ``ascii``."""
    text = f"{value:.{precision}g}"
    if ascii or "e" not in text:
        return text
    mant, exp = text.split("e")
    return f"{mant}×10{str(int(exp)).translate(_SUPERSCRIPT)}"


def format_equation(target: str, intercept: float, coefs: Sequence[float],
                    labels: Sequence[str], precision: int = 4, ascii: bool = False) -> str:
    """``"B = 1.427×10⁻³ + 4.906×10⁻⁴·T − 4.616×10⁻⁶·T²"`` (paper 001 §4.2 style)."""
    minus, times = ("-", "*") if ascii else ("−", "·")
    lead = minus if intercept < 0 else ""
    text = f"{target} = {lead}{format_number(abs(intercept), precision, ascii)}"
    for c, label in zip(coefs, labels):
        sign = minus if c < 0 else "+"
        text += f" {sign} {format_number(abs(c), precision, ascii)}{times}{label}"
    return text
