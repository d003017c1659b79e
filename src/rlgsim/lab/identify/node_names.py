"""Where a device template's node is among the twin network's nodes.

A device template names its nodes as the device file does (``"A"``, ``"discharge"``); inside a
thermal network built from device blocks the same node is ``"<block>.<name>"``
(:mod:`rlgsim.sim.thermal.network`). The law, hop and scale-factor fits look nodes up by this one rule.
"""

from __future__ import annotations

__all__ = ["node_column"]


def node_column(block: str, name: str, names: tuple[str, ...]) -> int:
    """Column of node ``name`` among the twin network's ``names``: ``"block.name"`` when the
    network has it (a device block's node), else ``name`` itself (ValueError when neither)."""
    full = f"{block}.{name}" if block else name
    if full in names:
        return names.index(full)
    return names.index(name)
