"""The dataset schema: every group, dimension, variable, unit and description the simulator
writes, declared in this one room (docs/dataset.md is its prose).

The stages (:mod:`rlgsim.sim.stages`: where each model meets this schema) call
these functions once, before the first block, and then only append rows; the names are those
of :mod:`rlgsim.ground.dataset_format` (:data:`~rlgsim.ground.dataset_format.VARIABLES`,
checked by tests/test_imu.py), the one reader every module reads them with.

==========  ====================================================  =============================
group       what                                                  declared by
==========  ====================================================  =============================
timeline    labelled segments, chamber setpoint breakpoints       :func:`write_timeline`
thermal     chamber, power, true node temperatures, the unit's    :func:`declare_thermal`
            realised network
probes      thermometer readings and the probes' properties       :func:`declare_probes`
imu         pulses per sample, UHFO on the thermal grid           :func:`declare_imu`
turntable   table angles on the thermal grid, table of motions    :func:`declare_turntable`
truth       true sensor parameters and inputs, the drawn unit     :func:`declare_truth`
anomalies   the sensor anomalies' event record (optional)         :func:`declare_anomalies`
trajectory  a vehicle's position, velocity, attitude (optional)   :func:`declare_trajectory`
==========  ====================================================  =============================

Optional variables — parts a scenario switches on, named in
:data:`~rlgsim.ground.dataset_format.OPTIONAL_VARIABLES` and declared only when the part is on,
so runs without it keep their layout: the ``thermal`` group's heaters and further boundaries
(:func:`declare_thermal_parts`), the ``imu`` group's frame-validity flag
(:func:`declare_sample_valid`, IMU frame dropouts on) and the whole ``anomalies`` group
(:func:`declare_anomalies`, written by :class:`rlgsim.sim.stages.anomalies.AnomalyStage`).

Units are UDUNITS spellings ("1" for dimensionless and flags, none for strings); times are s
since the start of the run at the end of each thermal step (or IMU sample), absolute
temperatures °C.

Why this file is over 400 lines: it is the one room that declares every group of a dataset —
names (checked against rlgsim.ground.dataset_format), dimensions, units and descriptions — so a
reader of the format finds the whole layout in one place (docs/dataset.md is its prose).
"""

from __future__ import annotations

import json
from typing import Any, Sequence

import numpy as np

from rlgsim.ground import dataset_format as fmt
from rlgsim.sim.writer.dataset import DatasetWriter, GroupWriter
from rlgsim.sim.sensors.gyro import BODY_AXES

#: The ``description`` attribute of each group.
DESCRIPTIONS: dict[str, str] = {
    fmt.TIMELINE: "labelled segments of the run (chamber, power, turntable, calibration, "
                  "acquisition) and the chamber setpoint breakpoints",
    fmt.THERMAL: "chamber setpoint and air, power state and true node temperatures on the "
                 "thermal grid",
    fmt.PROBES: "thermometer probe readings on the thermal grid (what hardware would log)",
    fmt.IMU: "what the hardware outputs: gyro and accelerometer pulses per sample (int32) and "
             "the UHFO voltage on the thermal grid",
    fmt.TURNTABLE: "turntable angles and motion index at the end of each thermal step, and the "
                   "table of motions (labels for calibration)",
    fmt.TRUTH: "ground truth: every true sensor parameter on the thermal grid, the true inputs "
               "and the drawn device realisation",
    fmt.TRAJECTORY: "truth of a vehicle's motion: geodetic position, ENU ground velocity and "
                    "attitude at the end of each IMU sample, GNSS visibility, and the table of "
                    "legs",
    fmt.ANOMALIES: "truth: every sensor anomaly of the run (mode hops, pulse spikes, IMU frame "
                   "dropouts, probe glitches, stuck readings, probe dropouts), one row per event",
}

_TIME = "time since the start of the run at the end of each thermal step"


class _Listed:
    """A group writer that declares only the names :mod:`rlgsim.ground.dataset_format` lists
    for its group (:data:`~rlgsim.ground.dataset_format.VARIABLES` and
    :data:`~rlgsim.ground.dataset_format.OPTIONAL_VARIABLES`): the format owns the names, this
    room adds their dimensions, units and descriptions. A name the format does not list is a
    programming error (ValueError) before anything is written; the order and completeness of
    the declared names are checked by tests/test_imu.py and tests/test_dataset_optional.py."""

    def __init__(self, g: GroupWriter, group: str) -> None:
        self._g = g
        self._group = group
        self._names = set(fmt.VARIABLES.get(group, ())) | set(fmt.OPTIONAL_VARIABLES.get(group, ()))

    def _check(self, name: str) -> None:
        if name not in self._names:
            raise ValueError(f"the schema declares {self._group}/{name}, which "
                             f"rlgsim.ground.dataset_format does not list for group "
                             f"{self._group!r}; add it to VARIABLES or OPTIONAL_VARIABLES there")

    def dimension(self, name: str) -> None:
        self._check(name)
        self._g.dimension(name)

    def coordinate(self, name: str, *args: Any, **kwargs: Any) -> None:
        self._check(name)
        self._g.coordinate(name, *args, **kwargs)

    def variable(self, name: str, *args: Any, **kwargs: Any) -> None:
        self._check(name)
        self._g.variable(name, *args, **kwargs)

    def set_attrs(self, attrs: Any) -> None:
        self._g.set_attrs(attrs)


# --------------------------------------------------------------------------- timeline


def write_timeline(w: DatasetWriter, timeline) -> None:
    """The ``timeline`` group of a :class:`rlgsim.sim.run.schedule.Timeline`, written whole."""
    g = w.group(fmt.TIMELINE, DESCRIPTIONS[fmt.TIMELINE])
    g = _Listed(g, fmt.TIMELINE)  # type: ignore[assignment]
    segs = timeline.segments
    g.coordinate("segment", np.arange(len(segs), dtype=np.int32), units="1",
                 description="segment index", dtype=np.int32)
    g.variable("t0", ("segment",), units="s", data=np.array([s.t0_s for s in segs], float),
               description="segment start, s since the start of the run")
    g.variable("t1", ("segment",), units="s", data=np.array([s.t1_s for s in segs], float),
               description="segment end, s since the start of the run")
    g.variable("track", ("segment",), dtype=str, data=[s.track for s in segs],
               description=f"track of the segment: one of {', '.join(fmt.TRACKS)}")
    g.variable("label", ("segment",), dtype=str, data=[s.label for s in segs],
               description="human-readable label")
    g.variable(fmt.SEGMENT_DETAILS, ("segment",), dtype=str,
               data=[json.dumps(s.attrs, sort_keys=True, default=float) for s in segs],
               description="segment details as a JSON object (kind, temperatures, rates ...)")
    sp = timeline.setpoint
    g.coordinate("breakpoint", np.arange(len(sp.t_s), dtype=np.int32), units="1",
                 description="setpoint breakpoint index", dtype=np.int32)
    g.variable("setpoint_time", ("breakpoint",), units="s", data=np.asarray(sp.t_s, float),
               description="breakpoint time of the rate-limited chamber setpoint (linear in "
                           "between, last value held)")
    g.variable("setpoint", ("breakpoint",), units="degC", data=np.asarray(sp.y, float),
               description="chamber setpoint at the breakpoint")


# --------------------------------------------------------------------------- thermal


def declare_thermal(g: GroupWriter, nominal, realised) -> None:
    """The ``thermal`` group: growing ``time`` rows (``chamber_setpoint``, ``chamber_air``,
    ``power_on``, ``node_temperature``) and the simulated unit's network — ``realised`` values
    and their factors over the ``nominal`` :class:`rlgsim.sim.thermal.network.ThermalNetwork`."""
    g = _Listed(g, fmt.THERMAL)  # type: ignore[assignment]
    node_names = tuple(realised.node_names)
    g.coordinate("time", growing=True, units="s", description=_TIME)
    g.variable("chamber_setpoint", ("time",), units="degC",
               description="rate-limited chamber setpoint")
    g.variable("chamber_air", ("time",), units="degC",
               description="chamber air temperature (setpoint through the air lag)")
    g.variable("power_on", ("time",), units="1", dtype=np.int8,
               description="device power state held over the step ending at time (1 = on)")
    g.coordinate("node", node_names, description="thermal network node")
    g.variable("node_temperature", ("time", "node"), units="degC",
               description="true temperature of each thermal network node")
    # the drawn unit (ThermalNetwork.realise): realised values and factors over nominal
    nom, real = nominal, realised
    with np.errstate(divide="ignore", invalid="ignore"):
        def factor(r: np.ndarray, n: np.ndarray) -> np.ndarray:
            return np.where(n != 0, r / np.where(n != 0, n, 1.0), 1.0)
        for name, units, what, r, n in (
                ("capacitance", "J K-1", "heat capacity", real.capacitance_j_per_k,
                 nom.capacitance_j_per_k),
                ("ambient_conductance", "W K-1", "conductance to the chamber air",
                 real.ambient_conductance_w_per_k, nom.ambient_conductance_w_per_k),
                ("power", "W", "heat source when powered", real.power_w, nom.power_w)):
            g.variable(name, ("node",), units=units, data=r,
                       description=f"realised {what} of the node (this unit)")
            g.variable(f"{name}_factor", ("node",), units="1", data=factor(r, n),
                       description=f"drawn factor: realised / nominal {what} (1 where "
                                   f"the nominal value is 0)")
        iu, ju = np.nonzero(np.triu(nom.conductance_w_per_k > 0, k=1))
        names = node_names
        g.coordinate("link", [f"{names[i]}--{names[j]}" for i, j in zip(iu, ju)],
                     description="node-to-node link of the network ('a--b')")
        g.variable("link_conductance", ("link",), units="W K-1",
                   data=real.conductance_w_per_k[iu, ju],
                   description="realised conductance of the link (this unit)")
        g.variable("link_conductance_factor", ("link",), units="1",
                   data=real.conductance_w_per_k[iu, ju] / nom.conductance_w_per_k[iu, ju],
                   description="drawn factor: realised / nominal link conductance")


def declare_thermal_parts(g: GroupWriter, network) -> None:
    """The optional parts of the ``thermal`` group, declared after :func:`declare_thermal` and
    only for the parts the simulated :class:`rlgsim.sim.thermal.network.ThermalNetwork` has (nothing
    for a network without them, so such datasets keep their layout): ``heater``,
    ``heater_power`` (time, heater) [W] held over the step ending at time; ``boundary``,
    ``boundary_temperature`` (time, boundary) [°C] at time."""
    g = _Listed(g, fmt.THERMAL)  # type: ignore[assignment]
    if network.heaters:
        g.coordinate("heater", [h.name for h in network.heaters],
                     description="controlled heater of the network")
        g.variable("heater_power", ("time", "heater"), units="W",
                   description="power of the controlled heater, held over the step "
                               "ending at time")
    if network.boundaries:
        g.coordinate("boundary", [b.name for b in network.boundaries],
                     description="further boundary of the network (prescribed "
                                 "temperature)")
        g.variable("boundary_temperature", ("time", "boundary"), units="degC",
                   description="temperature of the further boundary at time")


# --------------------------------------------------------------------------- probes


def declare_probes(g: GroupWriter, probes, network) -> None:
    """The ``probes`` group of a :class:`rlgsim.sim.thermal.thermometers.ProbeSet` on ``network``:
    the probes' properties and the growing ``temperature`` rows."""
    g = _Listed(g, fmt.PROBES)  # type: ignore[assignment]
    names = tuple(probes.names)
    nodes = [network.node_names[i] for i in np.asarray(probes.node_index)]
    g.coordinate("time", growing=True, units="s", description=_TIME)
    g.coordinate("probe", names, description="thermometer probe")
    g.variable("probe_node", ("probe",), data=nodes, dtype=str,
               description="thermal network node each probe is mounted on")
    g.variable("tau", ("probe",), units="s", data=np.asarray(probes.tau_s),
               description="time constant of the probe's first-order lag")
    g.variable("noise_sigma", ("probe",), units="K", data=np.asarray(probes.noise_sigma_c),
               description="standard deviation of the probe's white reading noise")
    g.variable("resolution", ("probe",), units="K", data=np.asarray(probes.resolution_c),
               description="reading resolution (quantisation step; 0 = none)")
    g.variable("temperature", ("time", "probe"), units="degC",
               description="probe reading (first-order lag, white noise, resolution)")


# --------------------------------------------------------------------------- IMU stage


def _pulses_storage(n: int) -> dict:
    """Pulses: lossless integer packing (HDF5 scale-offset) in chunks of 4096 samples, short
    enough that most hold no turntable rotation and pack into 1-2 bits per value (≈ 0.7 B per
    value at 100 Hz on paper 000's programme instead of 4; benchmarks)."""
    return {"scaleoffset": 0, "chunks": (4096, n)}


def declare_imu(g: GroupWriter, realisation, *, rate_hz: float, step_s: float) -> None:
    """The ``imu`` group of a drawn unit (:class:`rlgsim.sim.sensors.imu_model.ImuRealisation`): pulses along
    ``sample`` (no stored coordinate), UHFO along ``time``; accelerometer and UHFO variables
    only when the unit has them."""
    g = _Listed(g, fmt.IMU)  # type: ignore[assignment]
    gy, acc, uh = realisation.gyros, realisation.accels, realisation.uhfo
    g.set_attrs({"sample_rate_hz": rate_hz, "thermal_step_s": step_s,
                 "sample_time": "sample k covers [k/f, (k+1)/f); its time is (k+1)/f s "
                                "(f = sample_rate_hz); no coordinate is stored"})
    g.dimension("sample")
    g.coordinate("time", growing=True, units="s", description=_TIME)
    g.coordinate("gyro", gy.axes, description="gyro input axis (body axis)")
    g.variable("gyro_pulses", ("sample", "gyro"), units="1", dtype=np.int32,
               storage=_pulses_storage(gy.n),
               description="gyro pulses counted in each sample interval (paper 000 eq. 17)")
    if acc is not None:
        g.coordinate("accel", acc.axes, description="accelerometer input axis (body axis)")
        g.variable("accel_pulses", ("sample", "accel"), units="1", dtype=np.int32,
                   storage=_pulses_storage(acc.n),
                   description="accelerometer pulses counted in each sample interval "
                               "(paper 000 eq. 20)")
    if uh is not None:
        g.variable("uhfo", ("time", "gyro"), units="V", dtype=np.float32,
                   description="high-frequency-oscillator voltage of each gyro's "
                               "light-intensity loop as logged (read-out noise, ADC step)")


def declare_sample_valid(g: GroupWriter) -> None:
    """The ``imu`` group's frame-validity flag, declared after :func:`declare_imu` and only
    when the device's ``[anomalies]`` table has IMU frame dropouts (:mod:`rlgsim.sim.sensors.anomalies`)."""
    g = _Listed(g, fmt.IMU)  # type: ignore[assignment]
    g.variable("sample_valid", ("sample",), units="1", dtype=np.int8,
               description="1 if the IMU frame reached the log, 0 if it was lost (its pulses "
                           "are 0 here; the lost counts are in the anomalies group)")


def declare_turntable(g: GroupWriter, segments: Sequence[Any]) -> None:
    """The ``turntable`` group: angles and motion index along ``time`` and the table of the
    timeline's turntable ``segments`` (dimension ``motion``)."""
    g = _Listed(g, fmt.TURNTABLE)  # type: ignore[assignment]
    segs = segments
    g.coordinate("time", growing=True, units="s", description=_TIME)
    g.variable("outer_angle", ("time",), units="degree",
               description="outer-axis angle at the end of the step (rlgsim.sim.turntable)")
    # (the module names in stored descriptions are data of the format: they name the rooms as they
    # were when the format was fixed — rlgsim.sim.turntable is now rlgsim.sim.motion.turntable)
    g.variable("inner_angle", ("time",), units="degree",
               description="inner-axis angle at the end of the step")
    g.variable("motion_index", ("time",), units="1", dtype=np.int32,
               description="index (dimension motion) of the turntable motion in which the "
                           "step ends")
    g.coordinate("motion", np.arange(len(segs), dtype=np.int32), units="1", dtype=np.int32,
                 description="turntable motion index (timeline track 'turntable')")
    attr = [dict(s.attrs) for s in segs]

    def col(key, default):
        return [a.get(key) if a.get(key) is not None else default for a in attr]
    g.variable("motion_t0", ("motion",), units="s", data=np.array([s.t0_s for s in segs]),
               description="start of the motion")
    g.variable("motion_t1", ("motion",), units="s", data=np.array([s.t1_s for s in segs]),
               description="end of the motion")
    g.variable("motion_label", ("motion",), dtype=str, data=[s.label for s in segs],
               description="label of the motion")
    g.variable("motion_kind", ("motion",), dtype=str, data=col("kind", "static"),
               description="'static' or 'rotate'")
    g.variable("motion_axis", ("motion",), dtype=str, data=col("axis", ""),
               description="rotating table axis ('outer', 'inner', '' when static)")
    g.variable("motion_rate", ("motion",), units="degree s-1",
               data=np.array(col("rate_deg_s", 0.0), dtype=float),
               description="signed table rate during the motion")
    g.variable("motion_position", ("motion",), units="1", dtype=np.int32,
               data=np.array(col("position", -1), dtype=np.int32),
               description="1-based position within the programme (-1: none)")
    g.variable("motion_window", ("motion",), units="1", dtype=np.int32,
               data=np.array(col("window", -1), dtype=np.int32),
               description="calibration window (-1: not a calibration)")


def declare_truth(g: GroupWriter, realisation, *, seed: int, unit: int, rate_hz: float,
                  step_s: float, gyro_white_sigma: np.ndarray, accel_white_sigma: np.ndarray,
                  truth_samples: bool) -> None:
    """The ``truth`` group of a drawn unit: its coefficient table, the true parameters and
    inputs along ``time`` (per ``sample`` too when ``truth_samples``), the white-noise σ per
    sample (gyro [rad], accelerometer [m/s]) and, as attributes, the recipes that reproduce the
    pulses (docs/dataset.md "Reproducing the pulses")."""
    g = _Listed(g, fmt.TRUTH)  # type: ignore[assignment]
    gy, acc, uh = realisation.gyros, realisation.accels, realisation.uhfo
    names, values, unit_list = realisation.coefficient_table()
    g.set_attrs({
        "seed": np.int64(seed), "unit": np.int64(unit),
        "sample_rate_hz": rate_hz, "thermal_step_s": step_s,
        "parameter_hold": "every parameter row holds over the samples of its thermal step "
                          "(samples whose mid-point lies in [time - thermal_step_s, time))",
        "white_noise": "block b (600 s) of axis a: z = rlgsim.sim.rng.generator(seed, unit, "
                       "'gyro.white' | 'accel.white', a, b).standard_normal(n_b, "
                       "dtype=float32); increment = float64(z) * white_sigma",
        "gyro_equation": "u = ((E_x dth_x + E_y dth_y) + E_z dth_z) + bias*dt; u = u + "
                         "sigma*z; inc = K*u [pulses]; pulses: rlgsim.sim.pulses fixed point",
        "accel_equation": "u = ((E_x dv_x + E_y dv_y) + E_z dv_z) + bias*dt; u = u + "
                          "sigma*z; inc = (K+ if u >= 0 else K-)*u [pulses]",
    })
    g.coordinate("time", growing=True, units="s", description=_TIME)
    g.coordinate("body", BODY_AXES, description="body (measurement) axis")
    g.coordinate("gyro", gy.axes, description="gyro input axis (body axis)")
    g.coordinate("coefficient", names,
                 description="drawn coefficient of the unit: <law>.<term>[<axis>]")
    g.variable("coefficient_value", ("coefficient",), data=values,
               units="per coefficient: see coefficient_units",
               description="value of the drawn coefficient")
    g.variable("coefficient_units", ("coefficient",), dtype=str, data=unit_list,
               description="unit of the coefficient (preset units)")
    g.variable("gyro_bias", ("time", "gyro"), units="rad s-1",
               description="true gyro bias D_g (temperature law + flicker + rate random "
                           "walk), held over the step")
    g.variable("gyro_bias_random", ("time", "gyro"), units="rad s-1",
               description="the flicker + rate-random-walk part of gyro_bias")
    g.variable("gyro_scale_factor", ("time", "gyro"), units="rad-1",
               description="true gyro scale factor K_g [pulses/rad]")
    g.variable("gyro_installation", ("time", "gyro", "body"), units="1",
               description="true gyro installation matrix rows E_g (1 on the own axis, "
                           "misalignment angles [rad] off it)")
    g.variable("gyro_white_sigma", ("gyro",), units="rad", data=gyro_white_sigma,
               description="standard deviation of the white angle increment per sample "
                           "(ARW·sqrt(1/f))")
    if acc is not None:
        g.coordinate("accel", acc.axes, description="accelerometer input axis (body axis)")
        g.variable("accel_bias", ("time", "accel"), units="m s-2",
                   description="true accelerometer bias D_a (law + flicker + random walk)")
        g.variable("accel_bias_random", ("time", "accel"), units="m s-2",
                   description="the flicker + random-walk part of accel_bias")
        g.variable("accel_scale_factor_pos", ("time", "accel"), units="s m-1",
                   description="true positive-input scale factor K_a+ [pulses/(m/s)]")
        g.variable("accel_scale_factor_neg", ("time", "accel"), units="s m-1",
                   description="true negative-input scale factor K_a- [pulses/(m/s)]")
        g.variable("accel_installation", ("time", "accel", "body"), units="1",
                   description="true accelerometer installation matrix rows E_a")
        g.variable("accel_white_sigma", ("accel",), units="m s-1", data=accel_white_sigma,
                   description="standard deviation of the white velocity increment per "
                               "sample (VRW·sqrt(1/f))")
    if uh is not None:
        g.variable("uhfo_true", ("time", "gyro"), units="V",
                   description="true light-intensity-loop voltage (law + discharge wander), "
                               "before read-out noise and ADC")
        g.variable("uhfo_u0", ("gyro",), units="V", data=uh.u0,
                   description="U_0: the excitation the bias law's UHFO term is relative to")
    g.variable("dtheta_step", ("time", "body"), units="rad",
               description="true angle increment ∫ω_ib^b dt summed over the step's samples")
    g.variable("dv_step", ("time", "body"), units="m s-1",
               description="true velocity increment ∫f^b dt summed over the step's samples")
    if truth_samples:
        g.dimension("sample")
        g.variable("dtheta", ("sample", "body"), units="rad",
                   description="true angle increment ∫ω_ib^b dt over each sample interval")
        g.variable("dv", ("sample", "body"), units="m s-1",
                   description="true velocity increment ∫f^b dt over each sample interval")


# --------------------------------------------------------------------------- anomalies


def declare_anomalies(g: GroupWriter) -> None:
    """The ``anomalies`` group (only with an active ``[anomalies]`` device table; written by
    :class:`rlgsim.sim.stages.anomalies.AnomalyStage`): one row per event along the growing
    dimension ``event`` — start and end [s], channel, kind, size and the unit of the size
    (docs/sensors.md)."""
    g = _Listed(g, fmt.ANOMALIES)  # type: ignore[assignment]
    g.coordinate("event", growing=True, dtype=np.int64, units="1",
                 description="event index in order of time")
    g.variable("time", ("event",), units="s",
               description="start of the event: end of the first affected sample or "
                           "thermal step, s since the start of the run")
    g.variable("end", ("event",), units="s",
               description="end of the event (= time for single-sample events)")
    g.variable("channel", ("event",), dtype=str,
               description="gyro axis or probe name the event affects")
    g.variable("kind", ("event",), dtype=str,
               description="mode_hop_up, mode_hop_down, pulse_spike, imu_dropout, "
                           "probe_glitch, probe_stuck or probe_dropout")
    g.variable("size", ("event",), units="see size_units",
               description="bias step [deg/h], extra or lost pulses, replaced minus true "
                           "reading [degC] or duration [s]")
    g.variable("size_units", ("event",), dtype=str, description="unit of size")


# --------------------------------------------------------------------------- trajectory


def declare_trajectory(g: GroupWriter, trajectory) -> None:
    """The ``trajectory`` group of a run on a vehicle (:class:`rlgsim.sim.motion.trajectory.
    Trajectory`): the states at the end of each IMU sample along ``sample`` (no stored
    coordinate, as in ``imu``) and the table of the legs (dimension ``leg``)."""
    g = _Listed(g, fmt.TRAJECTORY)  # type: ignore[assignment]
    legs = trajectory.legs
    g.set_attrs({"frames": "navigation frame ENU at the vehicle; body axes x right, y forward, "
                           "z up; C_b^n = R_z(-heading) R_x(pitch) R_y(roll)",
                 "initial_longitude_deg": float(np.degrees(trajectory.initial.lon_rad))})
    g.dimension("sample")
    g.coordinate("enu", ["east", "north", "up"], description="navigation-frame axis")
    g.coordinate("quaternion", ["w", "x", "y", "z"],
                 description="component of a Hamilton quaternion, scalar first")
    g.variable("latitude", ("sample",), units="degree",
               description="geodetic latitude (WGS-84) at the end of the sample")
    g.variable("longitude", ("sample",), units="degree",
               description="longitude at the end of the sample")
    g.variable("height", ("sample",), units="m",
               description="height above the WGS-84 ellipsoid at the end of the sample")
    g.variable("velocity", ("sample", "enu"), units="m s-1",
               description="ground velocity in ENU at the end of the sample")
    g.variable("attitude", ("sample", "quaternion"), units="1",
               description="attitude q_b^n (body to ENU) at the end of the sample")
    g.variable("heading", ("sample",), units="degree",
               description="heading from North, clockwise, in [0, 360)")
    g.variable("pitch", ("sample",), units="degree", description="pitch, nose up")
    g.variable("roll", ("sample",), units="degree", description="roll, right wing down")
    g.variable("gnss_visible", ("sample",), units="1", dtype=np.int8,
               description="1 where a GNSS receiver sees the sky (the leg's flag)")
    t0 = np.concatenate([[0.0], np.cumsum([leg.duration_s for leg in legs])])
    g.coordinate("leg", np.arange(len(legs), dtype=np.int32), units="1", dtype=np.int32,
                 description="leg index")
    g.variable("leg_t0", ("leg",), units="s", data=t0[:-1], description="start of the leg")
    g.variable("leg_t1", ("leg",), units="s", data=t0[1:], description="end of the leg")
    g.variable("leg_label", ("leg",), dtype=str, data=[leg.label for leg in legs],
               description="label of the leg")
    g.variable("leg_kind", ("leg",), dtype=str, data=[leg.kind for leg in legs],
               description="'rate' (constant rates) or 'smooth' (quintic to a target)")
    g.variable("leg_gnss", ("leg",), units="1", dtype=np.int8,
               data=np.array([leg.gnss for leg in legs], dtype=np.int8),
               description="1 where a GNSS receiver sees the sky during the leg")


def trajectory_rows(trajectory, t_s: np.ndarray, states: dict[str, np.ndarray] | None = None
                    ) -> dict[str, np.ndarray]:
    """The ``trajectory`` group's rows along ``sample`` at sample end times ``t_s`` (from
    ``states`` = ``trajectory.truth(t_s)`` when already computed)."""
    st = states if states is not None else trajectory.truth(t_s)
    heading, pitch, roll = st["euler"].T
    return {"latitude": np.degrees(st["lat"]), "longitude": np.degrees(st["lon"]),
            "height": st["height"], "velocity": st["v_n"], "attitude": st["q_bn"],
            "heading": np.degrees(heading) % 360.0, "pitch": np.degrees(pitch),
            "roll": np.degrees(roll),
            "gnss_visible": trajectory.gnss_visible(t_s).astype(np.int8)}
