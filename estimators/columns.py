"""Named columns of equal length: the pandas-free table that carries input names to estimators.

A :class:`Columns` is an immutable, ordered ``{name: 1-D float64 array}`` with the array view
that scikit-learn needs (``shape``, ``__array__``), so it can be passed straight to ``fit`` /
``predict`` of the compensators in this package.  Estimators take the input names from it
(or from their ``feature_names`` parameter) and report them, e.g. in the stepwise equation
``B = 1.4e-3 + 4.9e-4·T − ...`` (paper 001 §4.2).  scikit-learn's own ``feature_names_in_``
is only filled from dataframes, which this project does not use.

Dict semantics: ``len(table)`` is the number of columns and iterating yields the names;
``table.n_samples`` / ``table.shape`` give the rows.  Values are stored as read-only float64
copies, so a table never changes after it is built.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike


__all__ = ["Columns", "resolve_input_names", "select_inputs"]

class Columns:
    """Ordered, immutable set of named 1-D float64 columns of equal length.

    Parameters
    ----------
    columns
        ``{name: values}`` mapping or iterable of ``(name, values)`` pairs.  Names are
        non-empty, unique strings; values are 1-D and all of the same length.  Units are
        whatever the caller's data carry (conventionally SI, temperatures in °C).
    """

    __slots__ = ("_data", "_values")

    def __init__(self, columns: Mapping[str, ArrayLike] | Iterable[tuple[str, ArrayLike]]):
        items = list(columns.items()) if isinstance(columns, Mapping) else list(columns)
        if not items:
            raise ValueError("Columns needs at least one column")
        data: dict[str, np.ndarray] = {}
        n_rows: int | None = None
        first = ""
        for name, values in items:
            if not isinstance(name, str) or not name:
                raise ValueError(f"column names must be non-empty strings, got {name!r}")
            if name in data:
                raise ValueError(f"duplicate column name {name!r}")
            arr = np.array(values, dtype=np.float64)  # copy: the table owns its data
            if arr.ndim != 1:
                raise ValueError(f"column {name!r} must be 1-D, got shape {arr.shape}")
            if n_rows is None:
                n_rows, first = arr.shape[0], name
            elif arr.shape[0] != n_rows:
                raise ValueError(f"mismatched column lengths: {first!r} has {n_rows} values, "
                                 f"{name!r} has {arr.shape[0]}")
            arr.flags.writeable = False
            data[name] = arr
        self._data = data
        self._values: np.ndarray | None = None

    @classmethod
    def from_array(cls, array: ArrayLike, names: Sequence[str]) -> Columns:
        """Build from a 2-D array of shape (n_samples, len(names)) (or 1-D for one name)."""
        arr = np.asarray(array, dtype=np.float64)
        if arr.ndim == 1:
            arr = arr[:, None]
        if arr.ndim != 2 or arr.shape[1] != len(names):
            raise ValueError(f"array of shape {arr.shape} does not match {len(names)} names")
        return cls((name, arr[:, i]) for i, name in enumerate(names))

    # --- dict-like view --------------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        """Column names, in order."""
        return tuple(self._data)

    def __getitem__(self, key: str | Sequence[str]) -> np.ndarray | Columns:
        """One column (read-only 1-D array) by name, or a :class:`Columns` for a list of names."""
        if isinstance(key, str):
            try:
                return self._data[key]
            except KeyError:
                raise KeyError(f"no column {key!r}; have {', '.join(self.names)}") from None
        return self.select(key)

    def __contains__(self, name: object) -> bool:
        return name in self._data

    def __iter__(self) -> Iterator[str]:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def items(self) -> Iterator[tuple[str, np.ndarray]]:
        """``(name, values)`` pairs in order."""
        return iter(self._data.items())

    def __repr__(self) -> str:
        return f"Columns({self.n_samples} rows: {', '.join(self.names)})"

    # --- array view for scikit-learn --------------------------------------------------------
    @property
    def n_samples(self) -> int:
        """Number of rows."""
        return next(iter(self._data.values())).shape[0]

    @property
    def shape(self) -> tuple[int, int]:
        """``(n_samples, n_columns)``, as for the equivalent 2-D array."""
        return (self.n_samples, len(self._data))

    @property
    def values(self) -> np.ndarray:
        """Read-only 2-D float64 array of shape (n_samples, n_columns), columns in order."""
        if self._values is None:
            values = np.column_stack(list(self._data.values()))
            values.flags.writeable = False
            self._values = values
        return self._values

    def __array__(self, dtype: Any = None, copy: bool | None = None) -> np.ndarray:
        values = self.values
        if dtype is not None and np.dtype(dtype) != values.dtype:
            return values.astype(dtype)
        return values.copy() if copy else values

    # --- building new tables ---------------------------------------------------------------
    def select(self, names: Iterable[str]) -> Columns:
        """New table with the named columns, in the order given."""
        names = list(names)
        missing = [n for n in names if n not in self._data]
        if missing:
            raise KeyError(f"no column(s) {', '.join(map(repr, missing))}; "
                           f"have {', '.join(self.names)}")
        return Columns((n, self._data[n]) for n in names)

    def with_columns(self, other: Mapping[str, ArrayLike] | Columns) -> Columns:
        """New table with ``other``'s columns appended (names must not clash)."""
        extra = other.items()
        return Columns(list(self._data.items()) + list(extra))

    def rows(self, index: slice | ArrayLike) -> Columns:
        """New table with the rows picked by ``index`` (slice, boolean mask or integer array)."""
        if not isinstance(index, slice):
            index = np.asarray(index)
        return Columns((n, v[index]) for n, v in self._data.items())


def resolve_input_names(X: Any, feature_names: Sequence[str] | None,
                        n_features: int) -> tuple[str, ...]:
    """Names of the ``n_features`` inputs of ``X`` at fit time.

    ``feature_names`` (an estimator parameter) wins; otherwise the names of a :class:`Columns`;
    otherwise ``x0, x1, ...``.  Raises ``ValueError`` if ``feature_names`` has the wrong length,
    repeats a name, or disagrees with the names of a :class:`Columns` input.
    """
    if feature_names is not None:
        if isinstance(feature_names, str):
            raise ValueError("feature_names must be a sequence of names, not one string")
        names = tuple(str(n) for n in feature_names)
        if len(names) != n_features:
            raise ValueError(f"feature_names has {len(names)} names but X has {n_features} "
                             "columns")
        if len(set(names)) != len(names):
            raise ValueError(f"feature_names repeats a name: {names}")
        if isinstance(X, Columns) and X.names != names:
            raise ValueError(f"feature_names {names} disagree with the column names of X "
                             f"{X.names}")
        return names
    if isinstance(X, Columns):
        return X.names
    if _is_dataframe(X):
        return tuple(X.columns)
    return tuple(f"x{i}" for i in range(n_features))


def _is_dataframe(X: Any) -> bool:
    """A pandas DataFrame (duck-typed, so this module never imports pandas): its column names
    are the input names, like a :class:`Columns`'."""
    return (hasattr(X, "columns") and hasattr(X, "iloc") and getattr(X, "ndim", 0) == 2
            and all(isinstance(c, str) for c in X.columns))


def select_inputs(X: Any, names: Sequence[str]) -> Any:
    """At predict time: pick the fitted inputs by name from a :class:`Columns`, else pass ``X``.

    A table may hold extra columns (e.g. the target); those are ignored.  A missing input is
    a ``ValueError`` naming it.
    """
    if isinstance(X, Columns):
        missing = [n for n in names if n not in X]
        if missing:
            raise ValueError(f"X lacks the input(s) the model was fitted on: "
                             f"{', '.join(missing)}; X has {', '.join(X.names)}")
        return X.select(names)
    if _is_dataframe(X):
        have = list(X.columns)
        missing = [n for n in names if n not in have]
        if missing:
            raise ValueError(f"X lacks the input(s) the model was fitted on: "
                             f"{', '.join(missing)}; X has {', '.join(have)}")
        return X[list(names)]
    return X
