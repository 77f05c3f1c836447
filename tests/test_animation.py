"""Specification of baslip.viz.animation and the ``animate`` command: GIFs of gaits under
every hip law, with the trunk drawn as the rod that has the body's inertia, and bad input
refused before anything is written."""

import pytest
from PIL import Image
from runs import ROOT

from baslip import Params
from baslip.cli.animate import main
from baslip.viz.animation import trunk_half_length


@pytest.mark.parametrize("params", [Params(), Params(m=80.0, I=4.58, k=20000.0, rho0=1.0, d=0.1)])
def test_the_drawn_trunk_is_the_uniform_rod_with_the_bodys_inertia(params):
    length = 2 * trunk_half_length(params)
    assert params.m * length**2 / 12 == pytest.approx(params.I, rel=1e-12)


def test_a_vpp_gait_is_animated_large_enough_to_read(tmp_path, capsys):
    assert main([str(ROOT / "problems" / "vpp.yaml"), "--out", str(tmp_path)]) == 0
    gif = Image.open(tmp_path / "vpp.gif")
    assert gif.size[0] >= 600 and gif.n_frames > 20
    assert "wrote" in capsys.readouterr().out


def test_a_bad_problem_among_several_writes_nothing(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nfix: {z: -1}\n")
    out = tmp_path / "gifs"
    assert main([str(ROOT / "problems" / "vpp.yaml"), str(bad), "--out", str(out)]) == 2
    assert not out.exists()
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "fix.z" in err


def _short_hop():
    """A made-up tenth of a second of flight: eight frames, enough to watch the progress."""
    import numpy as np

    from baslip.engine.trajectory import Trajectory

    t = np.linspace(0.0, 0.1, 5)
    return Trajectory(t=t, y=0.5 * t, z=0.4 - t, theta_h=np.full(5, -1.5), foot_y=0.5 * t, foot_z=0.2 - t,
                      stance=np.zeros(5, dtype=bool))


def test_an_animation_says_which_frame_it_is_at_every_10_s_and_quiet_silences_it(monkeypatch, fake_clock, tmp_path):
    """Frames that take 3 s each on a fake clock (a stub in front of the GIF writer's
    grab): the frame reached is logged at least every 10 s, and nothing when INFO is not
    shown."""
    from matplotlib.animation import PillowWriter

    from baslip import diagnostics
    from baslip.viz.animation import animate

    grab = PillowWriter.grab_frame

    def slow_grab(writer, **savefig_kwargs):
        diagnostics.CLOCK.advance(3.0)
        return grab(writer, **savefig_kwargs)

    monkeypatch.setattr(PillowWriter, "grab_frame", slow_grab)
    clock = fake_clock()
    animate(_short_hop(), Params(), "a hop", tmp_path / "hop.gif")
    frames = Image.open(tmp_path / "hop.gif").n_frames
    assert frames == 8 and clock.time == pytest.approx(24.0)
    assert clock.messages() == ["animating a hop: frame 3 of 8, 9 s", "animating a hop: frame 6 of 8, 18 s"]
    assert clock.longest_silence() <= 10.0 and clock.running() == 0

    quiet = fake_clock(shown=False)
    animate(_short_hop(), Params(), "a hop", tmp_path / "quiet.gif")
    assert quiet.time == pytest.approx(24.0) and quiet.said == [] and quiet.running() == 0
