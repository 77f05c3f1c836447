"""Animated GIFs of gaits: trunk, hip, spring leg, ground and foot contact.

Drawing only: a gait's sampled motion (:mod:`baslip.engine.trajectory`) in slow motion.
The command that solves problems and writes their GIFs is :mod:`baslip.cli.animate`.
"""

from __future__ import annotations

import base64
import html
import math
import tempfile
from dataclasses import dataclass
from pathlib import Path

from baslip.diagnostics import heartbeat, logger
from baslip.viz.backend import use_file_backend

use_file_backend()
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.animation import FuncAnimation, PillowWriter  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from baslip.engine.codegen import FEW_CALLS  # noqa: E402
from baslip.engine.returnmap import ReturnMap, Tolerances  # noqa: E402
from baslip.engine.trajectory import Trajectory, stride_trajectory  # noqa: E402
from baslip.model.dynamics import Params  # noqa: E402
from baslip.model.hiplaw import PD, HipLaw  # noqa: E402

_log = logger(__name__)

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
    _save(animation, path, title)
    plt.close(fig)
    return path


def _save(animation: FuncAnimation, path: Path, title: str) -> None:
    """Write ``animation`` as a GIF to ``path``, saying every few seconds which frame it
    has reached: drawing a few hundred frames takes tens of seconds."""
    reached = [0, 0]  # frames drawn, frames in all

    def at(frame: int, frames: int) -> None:
        reached[:] = [frame + 1, frames]

    def still(elapsed: float) -> str:
        done, frames = reached
        stage = "writing the file" if frames and done == frames else f"frame {done} of {frames or '...'}"
        return f"animating {title}: {stage}, {elapsed:.0f} s"

    with heartbeat(_log, still):
        animation.save(path, writer=PillowWriter(fps=FPS), progress_callback=at)


@dataclass(frozen=True)
class GaitAnimation:
    """A gait's animation, one type everywhere: it shows itself in a notebook as an
    embedded GIF (no player or icons fetched from the web) and saves as a GIF.

    Attributes
    ----------
    figure : matplotlib.figure.Figure
        The figure the animation draws on (closed in pyplot: it shows no still frame).
    animation : matplotlib.animation.FuncAnimation
        The frames, in slow motion (:data:`SLOW_MOTION` animation seconds per simulated
        second, :data:`FPS` frames per second).
    title : str
        The figure's title, also in the GIF's alternative text in a notebook.
    """

    figure: Figure
    animation: FuncAnimation
    title: str

    def save(self, path: str | Path) -> Path:
        """Write the GIF to ``path`` (any suffix; the file is a GIF) and return the path.

        Parameters
        ----------
        path : str or Path
            The file to write.
        """
        path = Path(path)
        _save(self.animation, path, self.title)
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
    rmap = ReturnMap(Tolerances(1e-10, 1e-10), compile=FEW_CALLS, law=law)  # a few strides: see FEW_CALLS
    trajectory = stride_trajectory(rmap, X, u, params, strides=strides)
    fig, animation = _animation(trajectory, params, title)
    plt.close(fig)  # drawn by the animation alone: a notebook shows no extra still frame
    return GaitAnimation(fig, animation, title)


def trunk_half_length(params: Params) -> float:
    """Half the length of the trunk as drawn [m]: the uniform rod centred on the CoM that has
    the body's inertia, I = m L^2 / 12. (The model fixes only I and the hip's distance d
    from the CoM, so this is the one trunk its numbers imply.)"""
    return math.sqrt(3.0 * params.I / params.m)


def _animation(trajectory: Trajectory, params: Params, title: str):
    """(figure, FuncAnimation) of ``trajectory`` in slow motion, framed so that the whole
    runner, trunk ends included, stays inside; a legend and a clock in the corner."""
    frames = np.arange(0.0, trajectory.t[-1], 1.0 / (FPS * SLOW_MOTION))
    motion = trajectory.at(frames)
    fig, ax = plt.subplots(figsize=(6.4, 3.8), dpi=110)
    half = trunk_half_length(params)
    ends_y = motion.y[None, :] + np.array([[-half], [half]]) * np.cos(motion.theta_h)[None, :]
    ends_z = motion.z[None, :] + np.array([[-half], [half]]) * np.sin(motion.theta_h)[None, :]
    margin = 0.05 * max(params.rho0 / 0.2, 1.0)
    ax.set_xlim(min(ends_y.min(), motion.foot_y.min()) - margin, max(ends_y.max(), motion.foot_y.max()) + margin)
    ax.set_ylim(min(ends_z.min(), 0.0) - 0.03, max(motion.z.max(), ends_z.max(), 1.5 * params.rho0) + margin)
    ax.set_aspect("equal")
    ax.axhline(0.0, color="k", lw=1.5)
    ax.set_xlabel("y [m]")
    ax.set_ylabel("z [m]")
    ax.set_title(title, fontsize=9)
    (trunk,) = ax.plot([], [], color="tab:blue", lw=5, solid_capstyle="round", alpha=0.8, zorder=2,
                       label="trunk (rod of the body's inertia)")
    (leg,) = ax.plot([], [], color="tab:gray", lw=1.2, zorder=3, label="spring leg")
    (com,) = ax.plot([], [], "o", color="k", ms=4, zorder=4, label="centre of mass")
    (hip,) = ax.plot([], [], "o", color="tab:orange", ms=5, zorder=4, label="hip")
    (contact,) = ax.plot([], [], "^", color="tab:red", ms=8, zorder=4, label="foot on the ground")
    ax.legend(loc="center left", bbox_to_anchor=(1.02, 0.5), fontsize=7, frameon=False)
    clock = ax.text(0.02, 0.95, "", transform=ax.transAxes, fontsize=8, va="top")
    fig.tight_layout()

    def draw(k):
        c = np.array([motion.y[k], motion.z[k]])
        direction = np.array([np.cos(motion.theta_h[k]), np.sin(motion.theta_h[k])])
        h = c - params.d * direction
        trunk.set_data(*np.column_stack([c - half * direction, c + half * direction]))
        com.set_data([c[0]], [c[1]])
        hip.set_data([h[0]], [h[1]])
        leg.set_data(*spring_points(h, (motion.foot_y[k], motion.foot_z[k]), width=0.06 * params.rho0))
        contact.set_data(([motion.foot_y[k]], [0.0]) if motion.stance[k] else ([], []))
        clock.set_text(f"t = {frames[k]:.3f} s ({'stance' if motion.stance[k] else 'flight'}), "
                       f"{SLOW_MOTION:g}x slower")
        return leg, trunk, com, hip, contact, clock

    return fig, FuncAnimation(fig, draw, frames=len(frames), blit=True)
