"""Animated GIFs of gaits: trunk, hip, spring leg, ground and foot contact.

Drawing only: a gait's sampled motion (:mod:`baslip.engine.trajectory`) in slow motion.
The command that solves problems and writes their GIFs is :mod:`baslip.cli.animate`.
"""

from __future__ import annotations

import base64
import html
import tempfile
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.animation import FuncAnimation, PillowWriter  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from baslip.engine.returnmap import ReturnMap, Tolerances  # noqa: E402
from baslip.engine.trajectory import Trajectory, stride_trajectory  # noqa: E402
from baslip.model.dynamics import Params  # noqa: E402
from baslip.model.hiplaw import PD, HipLaw  # noqa: E402

SLOW_MOTION = 4.0  # animation seconds per simulated second
FPS = 20


def spring_points(hip, foot, coils: int = 6, width: float = 0.012):
    """A zig-zag from hip to foot: the spring leg."""
    hip, foot = np.asarray(hip), np.asarray(foot)
    axis = foot - hip
    length = np.hypot(*axis)
    normal = np.array([-axis[1], axis[0]]) / max(length, 1e-12)
    s = np.linspace(0, 1, 2 * coils + 3)
    offsets = np.zeros_like(s)
    offsets[2:-2] = width * np.where(np.arange(len(s) - 4) % 2 == 0, 1, -1)
    points = hip[None, :] + s[:, None] * axis[None, :] + offsets[:, None] * normal[None, :]
    return points[:, 0], points[:, 1]


def animate(trajectory: Trajectory, params: Params, title: str, path: Path) -> Path:
    """Write a GIF of ``trajectory`` to ``path``."""
    fig, animation = _animation(trajectory, params, title)
    animation.save(path, writer=PillowWriter(fps=FPS))
    plt.close(fig)
    return path


@dataclass(frozen=True)
class GaitAnimation:
    """A gait's animation, one type everywhere: it shows itself in a notebook as an
    embedded GIF (no player or icons fetched from the web) and saves as a GIF."""

    figure: Figure
    animation: FuncAnimation
    title: str

    def save(self, path: str | Path) -> Path:
        """Write the GIF to ``path`` (any suffix; the file is a GIF) and return the path."""
        path = Path(path)
        self.animation.save(path, writer=PillowWriter(fps=FPS))
        return path

    def gif(self) -> bytes:
        """The GIF's bytes."""
        with tempfile.TemporaryDirectory() as folder:
            return self.save(Path(folder) / "gait.gif").read_bytes()

    def _repr_html_(self) -> str:
        encoded = base64.b64encode(self.gif()).decode("ascii")
        return f'<img src="data:image/gif;base64,{encoded}" alt="{html.escape(self.title)}: animated gait">'


def notebook_animation(X, u, params: Params, title: str, strides: int = 2, law: HipLaw = PD) -> GaitAnimation:
    """The gait from apex ``X`` under control ``u`` of hip law ``law``, ``strides`` strides
    in slow motion, as a :class:`GaitAnimation`."""
    trajectory = stride_trajectory(ReturnMap(Tolerances(1e-10, 1e-10), law=law), X, u, params, strides=strides)
    fig, animation = _animation(trajectory, params, title)
    plt.close(fig)  # drawn by the animation alone: a notebook shows no extra still frame
    return GaitAnimation(fig, animation, title)


def _trunk_length(params: Params) -> float:
    return 3 * params.d + 0.04


def _animation(trajectory: Trajectory, params: Params, title: str):
    """(figure, FuncAnimation) of ``trajectory`` in slow motion, framed so that the whole
    runner, trunk tip included, stays inside."""
    frames = np.arange(0.0, trajectory.t[-1], 1.0 / (FPS * SLOW_MOTION))
    motion = trajectory.at(frames)
    fig, ax = plt.subplots(figsize=(5.0, 3.2), dpi=70)
    # The trunk runs from the hip to trunk_length beyond it: its tip can be the highest point.
    tip_y = motion.y + (_trunk_length(params) - params.d) * np.cos(motion.theta_h)
    tip_z = motion.z + (_trunk_length(params) - params.d) * np.sin(motion.theta_h)
    margin = 0.05
    ax.set_xlim(min(motion.y.min(), tip_y.min(), motion.foot_y.min()) - margin,
                max(motion.y.max(), tip_y.max(), motion.foot_y.max()) + margin)
    ax.set_ylim(-0.03, max(motion.z.max(), tip_z.max(), 0.3) + margin)
    ax.set_aspect("equal")
    ax.axhline(0.0, color="k", lw=1.5)
    ax.set_xlabel("y [m]")
    ax.set_ylabel("z [m]")
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    (leg,) = ax.plot([], [], color="tab:gray", lw=1.2)
    (trunk,) = ax.plot([], [], color="tab:blue", lw=5, solid_capstyle="round")
    (com,) = ax.plot([], [], "o", color="k", ms=4)
    (hip,) = ax.plot([], [], "o", color="tab:orange", ms=5)
    (contact,) = ax.plot([], [], "^", color="tab:red", ms=8)
    trunk_length = _trunk_length(params)

    def draw(k):
        c = np.array([motion.y[k], motion.z[k]])
        direction = np.array([np.cos(motion.theta_h[k]), np.sin(motion.theta_h[k])])
        h = c - params.d * direction
        trunk.set_data(*np.column_stack([h - 0.01 * direction, h + trunk_length * direction]))
        com.set_data([c[0]], [c[1]])
        hip.set_data([h[0]], [h[1]])
        leg.set_data(*spring_points(h, (motion.foot_y[k], motion.foot_z[k])))
        contact.set_data(([motion.foot_y[k]], [0.0]) if motion.stance[k] else ([], []))
        return leg, trunk, com, hip, contact

    return fig, FuncAnimation(fig, draw, frames=len(frames), blit=True)
