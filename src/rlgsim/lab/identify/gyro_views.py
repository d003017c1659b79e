"""One device preset for several gyros identified one at a time (docs/identify.md, "Several
gyros"): the single-gyro view of a device template that each gyro's fit reads
(:func:`gyro_view`), and the merge of the per-gyro twins back into one device preset
(:func:`merge_devices`).

The device format already holds a law per gyro: every number of a law table
(:mod:`rlgsim.sim.sensors.temperature_laws`; ``[gyro.bias]``, ``[gyro.scale_factor]``,
``[gyro.misalignment]``, the law keys of ``[uhfo]`` and their ``[tolerance.…]`` tables) is a
scalar (every gyro) or an array with one value per component — one per gyro, two per gyro for
the misalignment — and a gradient's coefficient likewise. The merge writes an array where the
gyros differ and a scalar where they agree, so a unit whose gyros share a law reads as before.
A term one gyro's recording selected and another's did not is 0 for the other (its law
default: 25 °C and 5 K for a knee's centre and width, 40 °C and 1 K for a step's, which a 0
amplitude makes irrelevant); gradient pairs are the union, 0 for a gyro that did not select
the pair.

What the format holds once per device is pooled, and the comment beside it gives every gyro's
own value: the law's ``node`` and ``t_ref_c`` (the template's, the same for every gyro), the
``[noise]`` levels and the UHFO wander and read-out noise (the mean over the gyros that
gave one), the ``[anomalies]`` tables (mode hops: the gyro with the most hops found; read-out
spikes: the mean rate and the largest size). A gyro without a UHFO column keeps the
template's UHFO law (its channel is simulated, and its bias law has no UHFO term).
"""

from __future__ import annotations

import copy
from typing import Any, Sequence

import numpy as np

from rlgsim.ground.errors import UserInputError

__all__ = ["gyro_view", "merge_devices", "template_component", "SCALAR_KEYS"]

#: keys the format holds once per table (never per gyro)
SCALAR_KEYS = {"node", "t_ref_c", "arm_nodes", "wander_v", "wander_tau_s", "noise_v", "lsb_v",
               "gradients_rel", "wander_rel", "noise_rel"}
#: law defaults of the keys that are not 0 by default (rlgsim.sim.sensors.temperature_laws)
_DEFAULTS = {"knee_c": 25.0, "knee_width_k": 5.0, "step_c": 40.0, "step_width_k": 1.0}
#: the laws of a ``[gyro]`` table and their components per gyro
GYRO_LAWS = {"bias": 1, "scale_factor": 1, "misalignment": 2}


def template_component(template: dict, axis: str, source: str) -> int:
    """Which gyro of the device template stands for the recorded gyro ``axis``: the only one of
    a single-gyro template (every recorded gyro on its block), else the one on the same axis."""
    axes = [str(a) for a in template.get("gyro", {}).get("axes", ["x", "y", "z"])]
    if len(axes) == 1:
        return 0
    if axis not in axes:
        raise UserInputError(f"{source}: gyro {axis!r} not allowed; the device template's gyros "
                             f"are {', '.join(axes)} (a single-gyro template stands for every "
                             f"recorded gyro)")
    return axes.index(axis)


def _part(v: Any, i: int, k: int) -> Any:
    """Component(s) ``i`` (``k`` per gyro) of a law value: a scalar is every gyro's."""
    if not isinstance(v, list):
        return v
    if len(v) == k:                      # already one gyro's (a single-gyro template)
        return v[0] if k == 1 else list(v)
    return v[i] if k == 1 else list(v[i * k:(i + 1) * k])


def _table_part(table: dict, i: int, k: int) -> dict:
    out = {}
    for key, v in table.items():
        if key == "gradients":
            out[key] = [{gk: (_part(gv, i, k) if gk.startswith("coeff_") else gv)
                         for gk, gv in g.items()} for g in v]
        elif key in SCALAR_KEYS or isinstance(v, dict):
            out[key] = copy.deepcopy(v)
        else:
            out[key] = _part(v, i, k)
    return out


def gyro_view(template: dict, axis: str, index: int) -> dict:
    """The single-gyro device template of gyro ``axis``, component ``index`` of ``template``:
    ``[gyro]`` with that axis and block and every law (``[uhfo]``, ``[tolerance.…]``) at that
    gyro's values — what each gyro's fit reads (:func:`rlgsim.lab.identify.law_fit.fit_laws`)."""
    dev = copy.deepcopy(template)
    g = dev.setdefault("gyro", {})
    blocks = g.get("blocks") or (["g"] if len(g.get("axes", ["x", "y", "z"])) == 1
                                 else [f"g{a}" for a in g.get("axes", ["x", "y", "z"])])
    g["axes"], g["blocks"] = [axis], [blocks[index]]
    for law, k in GYRO_LAWS.items():
        if law in g:
            g[law] = _table_part(g[law], index, k)
    if "uhfo" in dev:
        dev["uhfo"] = _table_part(dev["uhfo"], index, 1)
    tol = dev.get("tolerance", {})
    for law, k in GYRO_LAWS.items():
        if law in tol.get("gyro", {}):
            tol["gyro"][law] = _table_part(tol["gyro"][law], index, k)
    if "uhfo" in tol:
        tol["uhfo"] = _table_part(tol["uhfo"], index, 1)
    return dev


def _default(key: str, k: int, law: bool = True) -> Any:
    """A key's value for a gyro whose table lacks it: the law's default (0 for a tolerance)."""
    d = _DEFAULTS.get(key, 0.0) if law else 0.0
    return d if k == 1 else [d] * k


def _joined(values: list, k: int) -> Any:
    """Per-gyro values → one scalar when they agree, else the array (``k`` per gyro)."""
    flat = [x for v in values for x in ([v] * k if not isinstance(v, list) else v)]
    return flat[0] if all(x == flat[0] for x in flat) else flat


def _note(axes: Sequence[str], notes: list[str | None], what: str = "not selected (0)") -> str:
    """One comment for a merged key: every gyro's own, in axis order (``what`` for a gyro
    without one); one comment when every gyro has the same."""
    return _notes(axes, notes, [what] * len(notes))


def _merge_table(axes: Sequence[str], tables: list[dict | None], path: tuple,
                 comments: list[dict], k: int, missing: Sequence[str] | None = None,
                 law_defaults: bool = True) -> tuple[dict, dict]:
    """Merge one law table of every gyro (None: the gyro has none) and the comments at
    ``path`` + key; ``missing`` says per gyro what a key without a comment is (default: a
    term not selected); a key a gyro's table lacks is the law's default, or 0 without
    ``law_defaults`` (a tolerance: no spread)."""
    missing = list(missing or ["not selected (0)"] * len(tables))
    present = [t for t in tables if t is not None]
    keys: list[str] = []
    for t in present:
        keys += [key for key in t if key not in keys]
    out: dict = {}
    com: dict = {}
    for key in keys:
        if key == "gradients":
            out[key], com_g = _merge_gradients(axes, tables, path, comments, k)
            com.update(com_g)
            continue
        vals = [t.get(key, _default(key, k, law_defaults)) if t is not None
                else _default(key, k, law_defaults)
                for t in tables]
        notes = [c.get(path + (key,)) for c in comments]
        if key in SCALAR_KEYS:
            # the fitted values when some gyros fitted it (a comment), else every gyro's
            given = ([v for v, n in zip(vals, notes) if n is not None]
                     or [v for t, v in zip(tables, vals) if t is not None and key in t])
            fitted = [a for a, n in zip(axes, notes) if n is not None]
            out[key] = given[0] if all(v == given[0] for v in given) else float(np.mean(given))
            if fitted and len(fitted) < len(axes):
                own = "; ".join(f"{a}: {v:.4g} ({n})" for a, v, n in zip(axes, vals, notes)
                                if n is not None)
                com[path + (key,)] = (f"from gyro {', '.join(fitted)} (the format holds one "
                                      f"value for every gyro): {own}")
                continue
            if len(set(map(str, given))) > 1:
                own = "; ".join(f"{a}: {v:.4g} ({n})" for a, v, n in zip(axes, vals, notes))
                com[path + (key,)] = ("the mean of the gyros' (the format holds one value for "
                                      f"every gyro): {own}")
                continue
        else:
            out[key] = _joined(vals, k)
        if any(n is not None for n in notes):
            com[path + (key,)] = _notes(axes, notes, missing)
    return out, com


def _notes(axes: Sequence[str], notes: list[str | None], missing: Sequence[str]) -> str:
    """:func:`_note` with a per-gyro text for a gyro without a comment."""
    if all(n == notes[0] for n in notes) and notes[0] is not None:
        return notes[0]
    return "; ".join(f"{a}: {n if n is not None else m}"
                     for a, n, m in zip(axes, notes, missing))


def _merge_gradients(axes, tables, path, comments, k) -> tuple[list, dict]:
    """The union of the gyros' gradient pairs, each coefficient per gyro (0 where a gyro did
    not select the pair), with every gyro's comment."""
    pairs: list[tuple[str, str, str]] = []
    for t in tables:
        for g in (t or {}).get("gradients", []):
            ck = next(x for x in g if x.startswith("coeff_"))
            if (g["a"], g["b"], ck) not in pairs:
                pairs.append((g["a"], g["b"], ck))
    out, com = [], {}
    for j, (a, b, ck) in enumerate(pairs):
        vals, notes = [], []
        for t, c in zip(tables, comments):
            grads = (t or {}).get("gradients", [])
            hit = [i for i, g in enumerate(grads) if (g["a"], g["b"]) == (a, b)]
            vals.append(grads[hit[0]].get(ck, 0.0) if hit else _default(ck, k))
            notes.append(c.get(path + ("gradients", hit[0], ck)) if hit else None)
        out.append({"a": a, "b": b, ck: _joined(vals, k)})
        if any(n is not None for n in notes):       # the gyros that selected the pair
            com[path + ("gradients", j, ck)] = "; ".join(
                f"{x}: {n}" for x, n in zip(axes, notes) if n is not None) + (
                "; 0 for the others" if None in notes else "")
    return out, com


def _pooled(axes, tables: list[dict | None], path: tuple, comments: list[dict]
            ) -> tuple[dict, dict]:
    """A table the format holds once per device (``[noise]``): numbers the gyros disagree on
    become their mean, with every gyro's value in the comment."""
    present = [t for t in tables if t is not None]
    out, com = dict(present[0]), {}
    for key in out:
        vals = [t.get(key) for t in tables if t is not None]
        notes = [c.get(path + (key,)) for c in comments]
        if all(v == vals[0] for v in vals):
            if any(n is not None for n in notes):
                com[path + (key,)] = _note(axes, notes)
            continue
        out[key] = float(np.mean([float(v) for v in vals]))
        per = [f"{float(t.get(key)):.4g}" + (f" ({n})" if n else "") if t is not None else None
               for t, n in zip(tables, notes)]
        com[path + (key,)] = ("the mean of the gyros' (the format holds one level for all "
                              "gyros): " + _note(axes, per, "none"))
    return out, com


def _anomalies(axes, devs: list[dict], comments: list[dict], laws: list) -> tuple[dict, dict]:
    """One ``[anomalies]`` table: mode hops from the gyro with the most hops found, read-out
    spikes pooled (the mean rate per channel, the largest size)."""
    have = [i for i, d in enumerate(devs) if "anomalies" in d]
    if not have:
        return {}, {}
    counts = [len(getattr(laws[i].hops, "hops", ()) or ()) if laws[i].hops is not None else 0
              for i in range(len(devs))]
    best = max(have, key=lambda i: counts[i])
    out = copy.deepcopy(devs[best]["anomalies"])
    com = {p: c for p, c in comments[best].items() if p[0] == "anomalies"}
    if "mode_hop" in out:
        first = ("anomalies", "mode_hop", next(iter(out["mode_hop"])))
        com[first] = (f"the mode-hop model of gyro {axes[best]} ({counts[best]} hop(s) found; "
                      f"the format holds one model for all gyros; every gyro's hops are in "
                      f"the report)" + (f"; {com[first]}" if first in com else ""))
    spikes = [devs[i]["anomalies"]["pulse_spikes"] for i in have
              if "pulse_spikes" in devs[i]["anomalies"]]
    if len(spikes) > 1:
        rates = [s["rate_per_h"] for s in spikes]
        out["pulse_spikes"] = {"rate_per_h": float(np.mean(rates)),
                               "max_pulses": int(max(s["max_pulses"] for s in spikes))}
        com[("anomalies", "pulse_spikes", "rate_per_h")] = (
            "the mean of the gyros' rates per channel: " + ", ".join(
                f"{f'{r:.3g}'}" for r in rates) + " per h")
        com[("anomalies", "pulse_spikes", "max_pulses")] = "the largest spike of any gyro"
    return out, com


def merge_devices(template: dict, axes: Sequence[str], devs: list[dict],
                  comments: list[dict], laws: list) -> tuple[dict, dict]:
    """One device preset from the per-gyro twins ``devs`` (single-gyro device dicts of
    :func:`rlgsim.lab.identify.twin_text.device_dict`, one per recorded gyro ``axes``, with their
    ``comments`` and law fits ``laws``) on the full ``template``: module docstring."""
    out = {k: copy.deepcopy(v) for k, v in template.items() if k != "run_to_run"}
    com: dict = {p: c for p, c in comments[0].items() if p[0] == "device"}
    out["device"] = copy.deepcopy(devs[0]["device"])
    g = out.setdefault("gyro", {})
    g["axes"] = list(axes)
    g["blocks"] = [d["gyro"]["blocks"][0] for d in devs]
    for law, k in GYRO_LAWS.items():
        tabs = [d["gyro"].get(law) for d in devs]
        if any(t is not None for t in tabs):
            g[law], c = _merge_table(axes, tabs, ("gyro", law), comments, k)
            com.update(c)
    tol = out.get("tolerance", {})
    for law, k in GYRO_LAWS.items():
        tabs = [d.get("tolerance", {}).get("gyro", {}).get(law) for d in devs]
        if any(t is not None for t in tabs):
            tol["gyro"][law], _ = _merge_table(axes, tabs, ("tolerance", "gyro", law),
                                               comments, k, law_defaults=False)
    uh = [d.get("uhfo") for d in devs]
    if any(u is not None for u in uh):
        kept = ["not fitted (0)" if lf.uhfo is not None else "kept from the template (no UHFO "
                "column for this gyro; its bias law has no UHFO term)" for lf in laws]
        out["uhfo"], c = _merge_table(axes, uh, ("uhfo",), comments, 1, kept)
        com.update(c)
        tabs = [d.get("tolerance", {}).get("uhfo") for d in devs]
        if any(t is not None for t in tabs):
            tol["uhfo"], _ = _merge_table(axes, tabs, ("tolerance", "uhfo"), comments, 1,
                                          law_defaults=False)
    nz = [d.get("noise") for d in devs]
    if any(n is not None for n in nz):
        out["noise"], c = _pooled(axes, nz, ("noise",), comments)
        com.update(c)
    out.pop("anomalies", None)
    anomalies, c = _anomalies(axes, devs, comments, laws)
    if anomalies:
        out["anomalies"] = anomalies
        com.update(c)
    return out, com
