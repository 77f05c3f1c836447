"""The stance hip-torque law (thesis eq. 3.37) and the layout of the control vector.

``u = (Kp, Kd, theta2_des, theta2_dot_des, theta_td)``:

* ``Kp`` [N m/rad] and ``Kd`` [N m s/rad]: PD gains on the leg-trunk angle theta2;
* ``theta2_des`` [rad] and ``theta2_dot_des`` [rad/s]: their set points;
* ``theta_td`` [rad]: the leg angle from the vertical at which the massless leg is held in
  flight, and so the leg angle at touchdown.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from baslip.model.dynamics import STANCE
from baslip.model.layout import Layout

CONTROL = Layout(("Kp", "Kd", "theta2_des", "theta2_dot_des", "theta_td"))


@dataclass(frozen=True)
class Control:
    """Numeric control vector of one stride (units as in the module docstring)."""

    Kp: float
    Kd: float
    theta2_des: float
    theta2_dot_des: float
    theta_td: float

    def vector(self) -> np.ndarray:
        return CONTROL.pack(asdict(self))


def hip_torque(x, u):
    """PD hip torque [N m] in stance: tau = -Kp (th2 - th2_des) - Kd (th2dot - th2dot_des)."""
    c = CONTROL.unpack(u)
    theta2_error = STANCE.get(x, "theta2") - c["theta2_des"]
    theta2_rate_error = STANCE.get(x, "theta2_dot") - c["theta2_dot_des"]
    return -c["Kp"] * theta2_error - c["Kd"] * theta2_rate_error


def touchdown_angle(u):
    """The leg angle theta_td [rad] held through flight."""
    return CONTROL.get(u, "theta_td")
