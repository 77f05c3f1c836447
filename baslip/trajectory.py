"""Sampled motion of whole strides (CoM, trunk angle, foot), for drawing and animation.

Flight is sampled from its closed form, stance from the return map's integrator. The
horizontal position y accumulates over strides; the foot is on the ground in stance and
held at the touchdown angle (at rest length) in flight.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .control import CONTROL
from .model import APEX, Params, build_model
from .returnmap import ReturnMap, RunnerFell


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

    def at(self, times: np.ndarray) -> "Trajectory":
        """Linearly interpolated at ``times`` (the stance flag from the nearest sample)."""
        pick = np.clip(np.searchsorted(self.t, times), 0, len(self.t) - 1)
        interp = {name: np.interp(times, self.t, getattr(self, name)) for name in ("y", "z", "theta_h", "foot_y", "foot_z")}
        return Trajectory(t=np.asarray(times), stance=self.stance[pick], **interp)


def stride_trajectory(rmap: ReturnMap, X, u, params: Params, strides: int = 2, samples: int = 40) -> Trajectory:
    """Sample ``strides`` strides from apex ``X`` under control ``u``."""
    model = build_model()
    p = params.vector()
    theta_td = float(CONTROL.get(np.asarray(u), "theta_td"))
    parts, t0, y0, X = [], 0.0, 0.0, np.asarray(X, dtype=float)
    for _ in range(strides):
        stride = rmap.stride(X, u, params)
        if not stride.ok:
            raise RunnerFell(stride.fall)
        d = stride.durations
        # Descent, from the apex.
        a = APEX.unpack(X)
        flight = np.array([0.0, a["z"], a["theta_h"], a["ydot"], 0.0, a["theta_h_dot"]])
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


def trunk_angle_range(rmap: ReturnMap, X, u, params: Params, samples: int = 100) -> tuple[float, float]:
    """Least and greatest trunk angle theta_h [rad] over one stride from apex ``X``, from
    ``samples`` points in each of flight down, stance and flight up (flight is linear in
    time, so its ends are exact; stance is sampled)."""
    theta_h = stride_trajectory(rmap, X, u, params, strides=1, samples=samples).theta_h
    return float(np.min(theta_h)), float(np.max(theta_h))
