"""Which probe of the thermal template is each recorded probe? A lab names its thermometers
its own way (``block``, ``case_top``, ``T3``); the twin needs each one's place in the template's
network.

Two ways, in this order:

- the recording's sidecar says so: a ``[probes]`` table, recorded name → template probe
  (``block = "g.A"``); every recorded probe that is not already a template probe must be in it,
  every target must be a probe of the template and no two recorded probes may share one;
- otherwise identification proposes the mapping by fit and says so in one line: the template's
  network (at its design values, no multiplier fitted yet) is driven by the recorded chamber
  air and power (:func:`~rlgsim.lab.identify.thermal_fit.twin_response`), and each recorded
  probe is assigned to a distinct template probe so that the sum of the RMS differences between
  recorded and template readings is least (the linear assignment problem,
  :func:`scipy.optimize.linear_sum_assignment`). Probes already named as the template names them
  keep their name. The line gives, for each proposal, its RMS and the next-best template probe's,
  so a user sees where two template probes read alike (mirror points of a symmetric block) and
  the choice between them is a guess — the ``[probes]`` table then fixes it.

Any number of recorded probes from 2 up to the template's probe count is accepted (the thermal
fit uses the probes it has); more than the template has cannot be placed and is refused.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import linear_sum_assignment

from rlgsim.ground.errors import UserInputError
from rlgsim.lab.identify.recording_data import RecordingData

__all__ = ["map_probes", "sidecar_probe_table"]

#: fewest recorded probes an identification takes (one probe cannot tell the block from the
#: housing: every multiplier would trade against every other)
MIN_PROBES = 2


def sidecar_probe_table(source: str) -> dict[str, str]:
    """The sidecar's ``[probes]`` table of a recording ({} for a dataset or without one)."""
    from rlgsim.ground.recording import is_recording, read_sidecar, sidecar_path
    if not is_recording(source):
        return {}
    return dict(read_sidecar(sidecar_path(source)).probes)


def _apply(data: RecordingData, names: tuple[str, ...]) -> RecordingData:
    return dataclasses.replace(data, probe_names=names)


def map_probes(template: dict, data: RecordingData, table: dict[str, str] | None = None,
               source: str = "") -> tuple[RecordingData, list[str]]:
    """``data`` with its probes renamed to the template's probes, and the lines that say how
    (none when every probe already carries a template name). ``table``: the sidecar's
    ``[probes]`` (recorded → template). Bad tables and unplaceable probes: one
    :class:`~rlgsim.ground.errors.UserInputError` line."""
    from rlgsim.lab.identify.thermal_fit import build, twin_response
    net, probes = build(template, "thermal template")
    tnames = tuple(probes.names)
    rec = tuple(data.probe_names)
    where = source or data.source
    if len(rec) < MIN_PROBES:
        raise UserInputError(f"{where}: {len(rec)} probe temperature column(s); identification "
                             f"needs at least {MIN_PROBES} probes (probe_<name>_c), e.g. one on "
                             f"the gyro block and one on the housing")
    if len(rec) > len(tnames):
        raise UserInputError(f"{where}: {len(rec)} probes, but the thermal template has "
                             f"{len(tnames)} ({', '.join(tnames)}); each recorded probe needs a "
                             f"probe of the template (give another --thermal-template)")
    table = dict(table or {})
    for src, dst in table.items():
        if src not in rec:
            raise UserInputError(f"{where}: sidecar [probes] {src!r}: not a probe of the "
                                 f"recording (its probes: {', '.join(rec)})")
        if dst not in tnames:
            raise UserInputError(f"{where}: sidecar [probes] {src} = {dst!r}: not a probe of "
                                 f"the thermal template (its probes: {', '.join(tnames)})")
    named = {n: table.get(n, n) for n in rec}
    taken = [v for k, v in named.items() if k in table or v in tnames]
    dup = sorted({v for v in taken if taken.count(v) > 1})
    if dup:
        raise UserInputError(f"{where}: two recorded probes map to the template probe "
                             f"{dup[0]!r}; each template probe takes one recorded probe "
                             f"(sidecar [probes])")
    open_ = [n for n in rec if n not in table and n not in tnames]
    if not open_:
        if not table:
            return data, []
        return _apply(data, tuple(named[n] for n in rec)), [
            "probes mapped by the sidecar's [probes]: " + ", ".join(
                f"{k} → {v}" for k, v in table.items())]
    free = [t for t in tnames if t not in taken]
    _, reading = twin_response(net, probes, data.air_c, data.power, data.step_s)
    cost = np.empty((len(open_), len(free)))
    for i, n in enumerate(open_):
        x = data.probes_c[:, rec.index(n)]
        for j, t in enumerate(free):
            d = x - reading[:, tnames.index(t)]
            cost[i, j] = float(np.sqrt(np.nanmean(d ** 2)))
    rows, cols = linear_sum_assignment(cost)
    parts = []
    for i, j in zip(rows, cols):
        named[open_[i]] = free[j]
        others = np.delete(cost[i], j)
        nxt = (f"; next {free[int(np.argmin(np.where(np.arange(len(free)) == j, np.inf, cost[i])))]}"
               f" {others.min():.2f} °C" if others.size else "")
        parts.append(f"{open_[i]} → {free[j]} (RMS {cost[i, j]:.2f} °C{nxt})")
    side = (f"probes mapped by the sidecar's [probes]: "
            f"{', '.join(f'{k} → {v}' for k, v in table.items())}; the others " if table
            else "probes ")
    line = (side + "mapped by fit to the thermal template (RMS of the recorded reading "
            "against the template's, at its design values): " + ", ".join(parts)
            + "; a [probes] table in the sidecar (recorded name = \"template probe\") fixes the "
              "mapping where two template probes read alike")
    return _apply(data, tuple(named[n] for n in rec)), [line]
