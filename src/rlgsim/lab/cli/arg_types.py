"""Argument types of the command line's numeric options: a bad value is an
:class:`argparse.ArgumentTypeError` whose one line says what was expected (argparse prints it
after the option's name; :mod:`rlgsim.lab.cli.main` turns it into ``rlgsim: error: ...``)."""

from __future__ import annotations

import argparse
import math
from typing import Callable

__all__ = ["whole_number", "number"]


def whole_number(what: str = "a whole number") -> Callable[[str], int]:
    """Type of an option taking a whole number >= 1 (``what`` names it in the message)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if value < 1:
            raise argparse.ArgumentTypeError(f"value {text!r} not allowed; must be >= 1")
        return value
    return parse


def number(minimum: float, *, strict: bool, name: str = "") -> Callable[[str], float]:
    """Type of an option taking a finite number ``> minimum`` (``strict``) or ``>= minimum``;
    ``name`` says whose value it is in the message (``"ARW must be > 0"``)."""
    rule = f"{name + ' ' if name else ''}must be {'>' if strict else '>='} {minimum:g}"

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not math.isfinite(value) or value < minimum or (strict and value == minimum):
            raise argparse.ArgumentTypeError(f"value {text!r} not allowed; {rule}")
        return value
    return parse
