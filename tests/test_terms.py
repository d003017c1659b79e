"""Polynomial-term machinery: enumeration, labels, parsing, raw-unit expansion, equations."""

from __future__ import annotations

import numpy as np
import pytest

from rlgsim.estimators.terms import (design_matrix, format_equation, format_number, parse_term,
                              polynomial_powers, raw_coefficients, term_label, term_pretty)

NAMES = ("T", "dT/dt", "U")


def test_enumeration_counts_and_order():
    powers = polynomial_powers(3, 2)
    assert len(powers) == 9                                   # paper 001 Model 2 candidates
    assert [term_label(p, NAMES) for p in powers] == [
        "T", "dT/dt", "U", "T^2", "T*dT/dt", "T*U", "dT/dt^2", "dT/dt*U", "U^2"]
    assert len(polynomial_powers(2, 3)) == 9 and len(polynomial_powers(10, 3)) == 285
    assert polynomial_powers(2, 3, interaction=False) == [(1, 0), (0, 1), (2, 0), (0, 2),
                                                          (3, 0), (0, 3)]


def test_pretty_labels_follow_the_paper():
    assert term_pretty((2, 0, 0), NAMES) == "T²"
    assert term_pretty((0, 2, 0), NAMES) == "(dT/dt)²"
    assert term_pretty((1, 1, 0), NAMES) == "T·dT/dt"
    assert term_pretty((0, 1, 1), NAMES) == "dT/dt·U"
    grads = ("A-B", "A-C")
    assert term_pretty((1, 1), grads) == "(A-B)·(A-C)"
    assert term_pretty((2, 0), grads) == "(A-B)²"
    for p in polynomial_powers(2, 2):
        assert parse_term(term_pretty(p, grads), grads) == p
        assert parse_term(term_label(p, grads), grads) == p


@pytest.mark.parametrize("text, powers", [
    ("T", (1, 0, 0)), ("dT/dt", (0, 1, 0)), ("T^2", (2, 0, 0)), ("T²", (2, 0, 0)),
    ("(dT/dt)^2", (0, 2, 0)), ("(dT/dt)²", (0, 2, 0)), ("dT/dt^2", (0, 2, 0)),
    ("T*dT/dt", (1, 1, 0)), ("T·U", (1, 0, 1)), ("T * T", (2, 0, 0)), ((0, 0, 3), (0, 0, 3)),
])
def test_parse_term_reads_labels_and_exponents(text, powers):
    assert parse_term(text, NAMES) == powers


def test_parse_round_trips_every_label():
    for p in polynomial_powers(3, 3):
        assert parse_term(term_label(p, NAMES), NAMES) == p
        assert parse_term(term_pretty(p, NAMES), NAMES) == p


@pytest.mark.parametrize("bad, message", [
    ("V", r"'V' is not one of the inputs \(T, dT/dt, U\)"),
    ("T^0", "is not one of the inputs"),
    ((1, 0), "must be 3 non-negative exponents"),
    ((0, 0, 0), "not all 0"),
])
def test_parse_term_rejects_unknown_terms(bad, message):
    with pytest.raises(ValueError, match=message):
        parse_term(bad, NAMES)


def test_raw_expansion_of_shifted_scaled_terms_is_exact():
    rng = np.random.default_rng(0)
    X = rng.uniform(-3, 5, (50, 2))
    center, scale = np.array([1.0, -0.5]), np.array([4.0, 2.5])
    powers = polynomial_powers(2, 3)
    coef = rng.normal(size=len(powers))
    z_pred = 0.7 + design_matrix((X - center) / scale, powers) @ coef
    raw = raw_coefficients(powers, coef, 0.7, center, scale)
    raw_pred = sum(c * design_matrix(X, [p])[:, 0] if any(p) else c for p, c in raw.items())
    np.testing.assert_allclose(raw_pred, z_pred, rtol=1e-10)


def test_number_and_equation_format():
    assert format_number(1.427e-3) == "0.001427"
    assert format_number(-4.616e-6) == "-4.616×10⁻⁶"
    assert format_number(4.616e-6, ascii=True) == "4.616e-06"
    eq = format_equation("B", -1.565, [8.292e-3, -6.494e-2], ["T", "U²"])
    assert eq == "B = −1.565 + 0.008292·T − 0.06494·U²"
    assert format_equation("B", 1.0, [-2.0], ["T"], ascii=True) == "B = 1 - 2*T"
