"""User-facing errors.

A :class:`UserInputError` is a mistake by the user (a scenario file, a CLI argument, a dataset)
rather than a bug. The command line prints its message as one line and exits with code 2; it
never shows a traceback for one.
"""

from __future__ import annotations


__all__ = ["UserInputError", "location"]

class UserInputError(Exception):
    """A user mistake, described in one line: where (file/key), the value, what is allowed."""

    exit_code = 2

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message

    def __str__(self) -> str:
        return self.message


def location(source: str | None, key: str) -> str:
    """Format a ``file: key`` location for messages (``key`` alone when no file is known)."""
    return f"{source}: {key}" if source else key
