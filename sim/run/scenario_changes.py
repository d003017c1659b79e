"""A scenario with some keys changed, whose embedded TOML text says exactly what was run.

``Scenario`` is frozen and ``dataclasses.replace`` would leave ``scenario.text`` (the TOML
embedded in every dataset) stale. :func:`with_changes` changes the scenario's *TOML text*
instead and parses it again, so the result is validated like any scenario and its ``text``
parses to exactly the data it was built from::

    sc = load_scenario("quickstart")
    short = with_changes(sc, {"duration_h": 0.5, "chamber.segments[1].to_c": 35.0}, seed=7)

Keys are dotted paths into the TOML (``chamber.start_c``, ``site.latitude_deg``); a list
element is ``[i]`` (``chamber.segments[1].rate_c_per_min``); keyword arguments change
top-level keys. A value of ``None`` removes the key (e.g. ``duration_h=None`` to let the
chamber programme set the duration). Unknown keys and bad values are reported by the scenario
validator as for a file.

The original text is edited in place with tomlkit (:func:`rlgsim.ground.toml_text.with_values`),
so the comments and layout of the user's file survive; the text starts with a comment naming
the source and the changes.
"""

from __future__ import annotations

import tomllib
from typing import Any, Mapping

from rlgsim.ground.toml_text import dumps, value_text, with_values

__all__ = ["with_changes", "changed_text", "dumps_toml"]

#: TOML text for a parsed-TOML mapping (kept under its old name)
dumps_toml = dumps


def changed_text(scenario, changes: Mapping[str, Any]) -> str:
    """The TOML text of ``scenario`` with the dotted ``changes`` applied, headed by a comment
    naming the source and the changes; it parses to exactly ``scenario.tables`` with the
    changes. Parsing it is the caller's job (:meth:`rlgsim.sim.run.scenario.Scenario.with_changes`),
    so this module imports no scenario code."""
    try:
        original = scenario.text if tomllib.loads(scenario.text) == scenario.tables else None
    except (tomllib.TOMLDecodeError, TypeError):
        original = None
    text = with_values(original if original is not None else dumps(scenario.tables), changes)
    said = ", ".join(f"{k} = {value_text(v) if v is not None else '(removed)'}"
                     for k, v in changes.items())
    return f"# scenario {scenario.name}, from {scenario.source}, with {said}\n" + text


def with_changes(scenario, changes: Mapping[str, Any] | None = None, /, **keys: Any):
    """A new, validated :class:`~rlgsim.sim.run.scenario.Scenario`: ``scenario`` with the dotted
    ``changes`` and top-level ``keys`` applied; its ``text`` is the changed TOML."""
    return scenario.with_changes(changes, **keys)
