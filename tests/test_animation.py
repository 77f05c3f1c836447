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
