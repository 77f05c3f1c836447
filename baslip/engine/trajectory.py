"""Sampled motion of whole strides (CoM, trunk angle, foot), for drawing and animation.

Flight is sampled from its closed form, stance from the return map's integrator. The
horizontal position y accumulates over strides; the foot is on the ground in stance and
held at the touchdown angle (at rest length) in flight.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from baslip.engine import arguments
from baslip.engine.returnmap import ReturnMap, RunnerFell
from baslip.errors import ArgumentError
from baslip.model.dynamics import APEX, STANCE, Params, body_angle, build_model
from baslip.model.hiplaw import ground_force, touchdown_angle


@dataclass(frozen=True)
class Trajectory:
    """Samples in time: t [s]; CoM y, z [m]; theta_h [rad]; foot y, z [m]; stance flag."""

    t: np.ndarray
    y: np.ndarray
    z: np.ndarray
    theta_h: np.ndarray
    foot_y: np.ndarray
    foot_z: np.ndarray
    stance: np.ndarray

    def at(self, times: np.ndarray) -> Trajectory:
        """Linearly interpolated at ``times`` (the stance flag from the nearest sample)."""
        pick = np.clip(np.searchsorted(self.t, times), 0, len(self.t) - 1)
        interp = {name: np.interp(times, self.t, getattr(self, name)) for name in ("y", "z", "theta_h", "foot_y", "foot_z")}
        return Trajectory(t=np.asarray(times), stance=self.stance[pick], **interp)


#: Samples a stride takes per ``samples`` argument, at most: its descent, its stance's
#: two phases and its ascent (for the limit :data:`~baslip.engine.arguments.MAX_SAMPLES`).
PHASES_SAMPLED = 4


def checked_sampling(strides: object, samples: object) -> tuple[int, int]:
    """(strides, samples) of a trajectory or motion, checked: whole numbers, at least 1
    stride and 2 samples a phase, and at most :data:`~baslip.engine.arguments.MAX_SAMPLES`
    samples in all (4 x strides x samples); raises :class:`~baslip.errors.ArgumentError`
    naming the argument and giving the limit."""
    strides = arguments.whole_number(strides, "strides", 1, arguments.MAX_STRIDES)
    samples = arguments.whole_number(samples, "samples", 2, arguments.MAX_SAMPLES)
    total = PHASES_SAMPLED * strides * samples
    if total > arguments.MAX_SAMPLES:
        raise ArgumentError("samples", f"{strides} strides of {samples} samples a phase make {total:,} samples, "
                            f"beyond the limit of {arguments.MAX_SAMPLES:,} ({PHASES_SAMPLED} x strides x samples)")
    return strides, samples


def _checked_start(rmap: ReturnMap, X, u, params: Params) -> tuple[np.ndarray, np.ndarray]:
    """(X, u) as float vectors of ``rmap``'s sizes, and ``params`` a :class:`Params`."""
    if not isinstance(params, Params):
        raise ArgumentError("params", f"expected a Params, got {type(params).__name__}")
    return arguments.vector(X, "X", APEX.size), arguments.vector(u, "u", rmap.law.controls.size)


def stride_trajectory(rmap: ReturnMap, X, u, params: Params, strides: int = 2, samples: int = 40) -> Trajectory:
    """Sample ``strides`` strides from apex ``X`` [m, rad, m/s, rad/s] under control ``u``
    [SI, rad] of ``rmap``'s hip law, ``samples`` samples in each phase (descent, stance,
    ascent), with the runner of ``params``. Raises :class:`RunnerFell` if a stride falls,
    and :class:`~baslip.errors.ArgumentError` for arguments :func:`checked_sampling` refuses."""
    X, u = _checked_start(rmap, X, u, params)
    strides, samples = checked_sampling(strides, samples)
    model = build_model()
    p = params.vector()
    theta_td = float(touchdown_angle(np.asarray(u)))
    parts, t0, y0, X = [], 0.0, 0.0, np.asarray(X, dtype=float)
    for _ in range(strides):
        stride, flight = _stride_from(rmap, X, u, params, 0.0)
        d = stride.durations
        # Descent, from the apex.
        ts = np.linspace(0.0, d["descent"], samples)
        parts.append(_flight_samples(model, flight, ts, t0, y0, theta_td, params))
        # Stance, foot fixed where it touched down.
        xf_td = _ballistic(flight, d["descent"], params.g)
        x_td = np.asarray(model.touchdown_map(xf_td, theta_td, p)).ravel()
        foot_y = y0 + xf_td[0] - float(model.liftoff_map(x_td, p)[0])
        stance_time = d["compression"] + d["decompression"]
        states = rmap.stance_samples(x_td, u, params, stance_time, samples)
        cartesian = np.array([np.asarray(model.liftoff_map(states[:, k], p)).ravel() for k in range(samples)])
        ts = t0 + d["descent"] + np.linspace(0.0, stance_time, samples + 1)[1:]
        parts.append((ts, foot_y + cartesian[:, 0], cartesian[:, 1], cartesian[:, 2],
                      np.full(samples, foot_y), np.zeros(samples), np.ones(samples, dtype=bool)))
        # Ascent, to the next apex.
        lift = cartesian[-1].copy()
        lift[0] += foot_y
        ts = np.linspace(0.0, d["ascent"], samples)[1:]
        t_lift = t0 + d["descent"] + stance_time
        parts.append(_flight_samples(model, lift, ts, t_lift, 0.0, theta_td, params))
        t0, y0 = t_lift + d["ascent"], parts[-1][1][-1]
        X = stride.apex
    columns = [np.concatenate([part[i] for part in parts]) for i in range(7)]
    return Trajectory(*columns)


def _stride_from(rmap: ReturnMap, X, u, params: Params, y: float):
    """One stride from apex ``X``, and the flight state (y, z, theta_h, ydot, zdot,
    theta_h_dot) at that apex with the CoM at horizontal position ``y`` [m]; raises
    :class:`RunnerFell` if the stride falls."""
    stride = rmap.stride(X, u, params)
    if stride.fall is not None:
        raise RunnerFell(stride.fall)
    a = APEX.unpack(X)
    return stride, np.array([y, a["z"], a["theta_h"], a["ydot"], 0.0, a["theta_h_dot"]])


def _ballistic(xf, t, g):
    y, z, th, yd, zd, thd = xf
    return np.array([y + yd * t, z + zd * t - 0.5 * g * t * t, th + thd * t, yd, zd - g * t, thd])


def _flight_samples(model, xf, ts, t0, y0, theta_td, params: Params):
    states = np.array([_ballistic(xf, t, params.g) for t in ts])
    y, z, th = states[:, 0] + y0, states[:, 1], states[:, 2]
    hip_y, hip_z = y - params.d * np.cos(th), z - params.d * np.sin(th)
    foot_y = hip_y + params.rho0 * np.sin(theta_td)
    foot_z = hip_z - params.rho0 * np.cos(theta_td)
    return ts + t0, y, z, th, foot_y, foot_z, np.zeros(len(ts), dtype=bool)


class TrunkRange:
    """Least and greatest trunk angle theta_h [rad] over one stride, with the model built
    once: for the many strides of an atlas or a study.

    In flight the trunk turns at a constant rate, so its extremes there are the ends of
    the flight phases (the apexes, touchdown and liftoff), exactly; stance is sampled at
    ``samples`` instants (the last is liftoff), as :func:`stride_trajectory` samples it.
    """

    def __init__(self, rmap: ReturnMap, samples: int = 100):
        self.rmap, self.samples = rmap, arguments.whole_number(samples, "samples", 1, arguments.MAX_SAMPLES)
        self.model = build_model()

    def __call__(self, X, u, params: Params) -> tuple[float, float]:
        """(least, greatest) theta_h [rad] over the stride from apex ``X`` under ``u``;
        raises :class:`RunnerFell` if the stride falls."""
        stride, flight = _stride_from(self.rmap, X, u, params, 0.0)
        d = stride.durations
        theta_td = float(touchdown_angle(np.asarray(u)))
        x_touchdown = _ballistic(flight, d["descent"], params.g)
        x_stance = np.asarray(self.model.touchdown_map(x_touchdown, theta_td, params.vector())).ravel()
        states = self.rmap.stance_samples(x_stance, u, params, d["compression"] + d["decompression"], self.samples,
                                          compiled=True)
        stance = body_angle(states[STANCE.index("theta1")], states[STANCE.index("theta2")])
        angles = np.concatenate([[flight[2], x_touchdown[2], APEX.get(stride.apex, "theta_h")], stance])
        return float(np.min(angles)), float(np.max(angles))


def trunk_angle_range(rmap: ReturnMap, X, u, params: Params, samples: int = 100) -> tuple[float, float]:
    """Least and greatest trunk angle theta_h [rad] over one stride from apex ``X`` (see
    :class:`TrunkRange`, which builds the model once for many strides)."""
    return TrunkRange(rmap, samples)(X, u, params)


# --- the continuous motion, with velocities and forces ------------------------------------

#: Columns of a :class:`Motion` and their units.
MOTION_COLUMNS = {
    "t": "s", "stride": "", "phase": "", "y": "m", "z": "m", "ydot": "m/s", "zdot": "m/s",
    "hip_y": "m", "hip_z": "m", "hip_ydot": "m/s", "hip_zdot": "m/s", "theta_h": "rad", "theta_h_dot": "rad/s",
    "leg_length": "m", "leg_angle": "rad", "torque": "N m", "grf_y": "N", "grf_z": "N", "hip_power": "W",
    "energy": "J",
}
PHASE_NAMES = ("descent", "compression", "decompression", "ascent")


class UnknownColumn(ArgumentError, KeyError):
    """A column a :class:`Motion` does not have (a KeyError too, as for a mapping)."""

    __str__ = ArgumentError.__str__  # the one line, not KeyError's quoted repr


def _check_motion_columns(columns: object) -> None:
    """Raise :class:`ArgumentError` (naming ``columns``) unless ``columns`` maps exactly
    the names of :data:`MOTION_COLUMNS` to one-dimensional arrays of one length."""
    if not isinstance(columns, dict):
        raise ArgumentError("columns", f"expected a dict of column name to array, got {type(columns).__name__}")
    if set(columns) != set(MOTION_COLUMNS):
        missing = [n for n in MOTION_COLUMNS if n not in columns]
        extra = [arguments.shown(n) for n in columns if n not in MOTION_COLUMNS]
        what = [f"missing {_first(missing)}"] * bool(missing) + [f"unknown {_first(extra)}"] * bool(extra)
        raise ArgumentError("columns", f"expected the {len(MOTION_COLUMNS)} columns of MOTION_COLUMNS: {'; '.join(what)}")
    length = np.shape(columns["t"])
    odd = [n for n, v in columns.items() if np.ndim(v) != 1 or np.shape(v) != length]
    if odd:
        raise ArgumentError("columns", f"every column must be one-dimensional, as long as t ({length[0] if length else 0} "
                            f"samples): not {_first(odd)}")


def _first(names: list[str], most: int = 4) -> str:
    """The first ``most`` of ``names``, joined, and how many more there are."""
    shown = ", ".join(names[:most])
    return shown + (f" and {len(names) - most} more" if len(names) > most else "")


@dataclass(frozen=True)
class Motion:
    """The continuous motion of ``strides`` strides, sampled in time.

    Columns (:data:`MOTION_COLUMNS`): time t [s]; the stride (0, 1, ...) and its phase
    (descent, compression, decompression, ascent); CoM position y, z [m] and velocity
    ydot, zdot [m/s]; hip position and velocity; trunk angle theta_h [rad] and rate; leg
    length [m] and leg angle from the vertical [rad] (rest length and theta_td in
    flight); hip torque [N m] on the leg (zero in flight); ground reaction force grf_y,
    grf_z [N] (the spring's push along the leg and the torque's reaction across it, torque
    / leg length; zero in flight); hip power
    torque * theta2_dot [W], the rate of work of the hip motor; total mechanical energy [J].
    Touchdown and liftoff appear twice, at the end of the flight and at the start of the
    stance (or the other way round), so that flight and stance are each sampled from end
    to end.

    Attributes
    ----------
    columns : dict of str to numpy.ndarray
        Column name -> one value per sample; ``motion["z"]`` reads one column. ``phase``
        holds text, the others floats in SI units and radians.
    """

    columns: dict

    def __post_init__(self) -> None:
        _check_motion_columns(self.columns)

    def __getitem__(self, name: str) -> np.ndarray:
        if not isinstance(name, str) or name not in self.columns:
            raise UnknownColumn("name", f"no column {arguments.shown(name)} (expected one of {', '.join(self.columns)})")
        return self.columns[name]

    def __len__(self) -> int:
        return len(self.columns["t"])

    def __repr__(self) -> str:
        strides = int(self.columns["stride"][-1]) + 1 if len(self) else 0
        return f"Motion({strides} strides, {len(self)} samples, t = 0 to {self.columns['t'][-1]:.4g} s)"

    def _repr_html_(self) -> str:
        return f"<b>Motion</b>: {repr(self)[7:-1]}; columns {', '.join(self.columns)}"

    def csv_text(self) -> str:
        """The samples as CSV, a header of column names with units in brackets."""
        header = ",".join(f"{n} [{u}]" if u else n for n, u in MOTION_COLUMNS.items())
        lines = [header]
        for k in range(len(self)):
            lines.append(",".join(_cell(n, self.columns[n][k]) for n in MOTION_COLUMNS))
        return "\n".join(lines) + "\n"

    def to_dataframe(self):
        """A pandas DataFrame of the columns (needs pandas): ``stride`` as integers,
        ``phase`` as text, the rest floats in SI units and radians."""
        frame = _pandas().DataFrame({n: self.columns[n] for n in MOTION_COLUMNS})
        frame["stride"] = frame["stride"].astype("int64")
        return frame

    def work_of_torque(self) -> float:
        """The hip motor's work [J] over the samples: the trapezoidal integral of
        hip_power (touchdown and liftoff are sampled twice at the same time, so the jumps
        of the power there add nothing)."""
        t, power = self.columns["t"], self.columns["hip_power"]
        return float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(t)))


def _cell(name: str, value) -> str:
    if name == "phase":
        return str(value)
    if name == "stride":
        return str(int(value))
    return repr(float(value))


def _pandas():
    try:
        import pandas
    except ImportError:
        raise ImportError("to_dataframe needs pandas: pip install pandas") from None
    return pandas


def motion(rmap: ReturnMap, X, u, params: Params, strides: int = 1, samples: int = 100) -> Motion:
    """The motion of ``strides`` strides from apex ``X`` [m, rad, m/s, rad/s] under control
    ``u`` [SI, rad] of ``rmap``'s hip law, for the runner of ``params``, with ``samples``
    samples in each phase. Raises :class:`RunnerFell` if a stride falls, and
    :class:`~baslip.errors.ArgumentError` for arguments :func:`checked_sampling` refuses."""
    X, u = _checked_start(rmap, X, u, params)
    strides, samples = checked_sampling(strides, samples)
    model = build_model()
    p = params.vector()
    theta_td = float(touchdown_angle(u))
    rows: list[dict] = []
    t0, y0 = 0.0, 0.0
    for k in range(strides):
        stride, apex_state = _stride_from(rmap, X, u, params, y0)
        d = stride.durations
        for s in np.linspace(0.0, d["descent"], samples):
            rows.append(_flight_row(model, _ballistic(apex_state, s, params.g), t0 + s, k, "descent", theta_td, params, p))
        xf_td = _ballistic(apex_state, d["descent"], params.g)
        x_td = np.asarray(model.touchdown_map(xf_td, theta_td, p)).ravel()
        foot_y = xf_td[0] - float(model.liftoff_map(x_td, p)[0])
        t_td, stance_time = t0 + d["descent"], d["compression"] + d["decompression"]
        states = np.column_stack([x_td, rmap.stance_samples(x_td, u, params, stance_time, 2 * samples)])
        times = np.linspace(0.0, stance_time, 2 * samples + 1)
        for s, x in zip(times, states.T):
            phase = "compression" if s < d["compression"] else "decompression"
            rows.append(_stance_row(model, rmap.law, x, t_td + s, k, phase, foot_y, u, params, p))
        x_lo = states[:, -1]
        xf_lo = np.asarray(model.liftoff_map(x_lo, p)).ravel()
        xf_lo[0] += foot_y
        t_lo = t_td + stance_time
        for s in np.linspace(0.0, d["ascent"], samples):
            rows.append(_flight_row(model, _ballistic(xf_lo, s, params.g), t_lo + s, k, "ascent", theta_td, params, p))
        t0, y0 = t_lo + d["ascent"], _ballistic(xf_lo, d["ascent"], params.g)[0]
        X = stride.apex
    return Motion({n: np.array([r[n] for r in rows], dtype=object if n == "phase" else float) for n in MOTION_COLUMNS})


def _flight_row(model, xf, t, stride, phase, theta_td, params: Params, p) -> dict:
    y, z, th, yd, zd, thd = xf
    return {
        "t": t, "stride": stride, "phase": phase, "y": y, "z": z, "ydot": yd, "zdot": zd,
        "hip_y": y - params.d * np.cos(th), "hip_z": z - params.d * np.sin(th),
        "hip_ydot": yd + params.d * np.sin(th) * thd, "hip_zdot": zd - params.d * np.cos(th) * thd,
        "theta_h": th, "theta_h_dot": thd, "leg_length": params.rho0, "leg_angle": theta_td,
        "torque": 0.0, "grf_y": 0.0, "grf_z": 0.0, "hip_power": 0.0,
        "energy": float(model.flight_energy(xf, p)),
    }


def _stance_row(model, law, x, t, stride, phase, foot_y, u, params: Params, p) -> dict:
    xf = np.asarray(model.liftoff_map(x, p)).ravel()
    xf[0] += foot_y
    row = _flight_row(model, xf, t, stride, phase, 0.0, params, p)
    s = STANCE.unpack(x)
    torque = float(law.torque(ca.DM(x), ca.DM(u), ca.DM(p)))
    # The leg is massless, so the ground's force balances it: the spring's push along the
    # leg, foot to hip, and across it the hip torque's reaction, torque / rho.
    grf_y, grf_z = np.asarray(ground_force(ca.DM(x), torque, ca.DM(p))).ravel()
    row.update(
        leg_length=s["rho"], leg_angle=s["theta1"], torque=torque, grf_y=grf_y, grf_z=grf_z,
        hip_power=torque * s["theta2_dot"], energy=float(model.stance_energy(x, p)),
    )
    return row
