"""Specification of the command line, ``python -m baslip.solve PROBLEM.yaml [--out DIR]``.

Exit 0 and a verified result.json for a good problem; exit 1 with status "failed" when the
solver fails; exit 2, one line on stderr naming the key and nothing written for bad input.
"""

import csv
import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from baslip.cli.solve import main
from baslip.engine.codegen import cache_dir

ROOT = Path(__file__).resolve().parents[1]
RESULT_KEYS = [
    "name", "status", "solver", "params", "hip_law", "apex", "control", "durations",
    "energy", "residual", "eigenvalues", "spectral_radius", "stable", "on_bounds", "diagnosis", "provenance",
]


#: The libraries a first solve compiles (and a provenance names).
ENGINE_LIBRARIES = ("baslip_stride", "baslip_stride_jacobians", "baslip_nlp_1_20x1_rk4_objective", "baslip_events_rosenbrock")


def run_cli(*args, cwd=ROOT):
    return subprocess.run(
        [sys.executable, "-m", "baslip.solve", *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=600
    )


def test_downward_end_to_end(tmp_path):
    out = tmp_path / "downward"
    proc = run_cli("problems/downward.yaml", "--out", out)
    assert proc.returncode == 0, proc.stderr
    record = json.loads((out / "result.json").read_text())
    assert list(record) == RESULT_KEYS
    assert record["status"] == "converged" and record["residual"] <= 1e-10
    provenance = record["provenance"]
    assert provenance["problem"]["fix"] == {"ydot": 0.5, "z": 0.4} and len(provenance["problem_hash"]) == 64
    assert set(provenance["versions"]) == {"baslip", "casadi", "ipopt", "numpy", "python"}
    assert provenance["versions"]["ipopt"].count(".") == 2
    assert set(provenance["code"]) == set(ENGINE_LIBRARIES)
    assert all(route.startswith(("compiled C (", "CasADi virtual machine (")) for route in provenance["code"].values())
    assert record["apex"]["z"] == 0.4 and record["apex"]["ydot"] == 0.5
    assert "converged" in proc.stdout and "spectral radius" in proc.stdout
    assert (out / "multipliers.csv").read_text().startswith("re,im,abs,label\n")
    assert "Traceback" not in proc.stderr and "WARNING" not in proc.stderr


def test_a_gait_loads_neither_the_studies_nor_matplotlib(tmp_path, heavy_modules_after):
    """A single gait draws no figures: its run stays clear of the study modules and of
    matplotlib, which were a third of a warm run's start-up (0.76 s -> 0.37 s)."""
    statement = ("from baslip.cli.solve import main; "
                 f"result = main(['problems/downward.yaml', '--out', {str(tmp_path / 'downward')!r}, '--quiet'])")
    assert heavy_modules_after(statement) == ("0", [])


def run_with_cache_that_is_a_file(tmp_path, problem, out):
    blocker = tmp_path / "cache-is-a-file"
    blocker.write_text("")
    env = {**os.environ, "BASLIP_CACHE_DIR": str(blocker)}
    env.pop("BASLIP_NO_COMPILE", None)
    return subprocess.run([sys.executable, "-m", "baslip.solve", str(problem), "--out", str(out)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600, env=env)


def vm_routes(code: dict) -> bool:
    return bool(code) and all(r.startswith("CasADi virtual machine (the compiled-code cache") for r in code.values())


def test_provenance_records_the_virtual_machine_when_it_ran(tmp_path):
    """A cache that cannot be written: every library runs in the VM, the provenance says
    so per library (not "compiled C"), and the notice is one line that blames the cache."""
    out = tmp_path / "vm"
    proc = run_with_cache_that_is_a_file(tmp_path, "problems/downward.yaml", out)
    assert proc.returncode == 0, proc.stderr
    code = json.loads((out / "result.json").read_text())["provenance"]["code"]
    assert set(code) == set(ENGINE_LIBRARIES) and vm_routes(code)
    notices = [line for line in proc.stderr.splitlines() if line.startswith("baslip: ")]
    assert len(notices) == 1 and "not a folder" in notices[0] and "C compiler" not in notices[0]


def test_a_study_records_what_its_workers_ran_and_tells_once(tmp_path):
    problem = tmp_path / "grid.yaml"
    problem.write_text((ROOT / "problems" / "grid_downward.yaml").read_text().replace(
        "vary: {ydot: [0.1, 1.0, 0.1], z: [0.3, 0.7, 0.05]}", "vary: {ydot: [0.4, 0.5, 0.1], z: [0.4, 0.4, 0.05]}"))
    out = tmp_path / "grid"
    proc = run_with_cache_that_is_a_file(tmp_path, problem, out)
    assert proc.returncode == 0, proc.stderr
    code = json.loads((out / "result.json").read_text())["provenance"]["code"]
    assert {"baslip_stride", "baslip_nlp_1_20x1_rk4_objective"} <= set(code) and vm_routes(code)
    assert sum(line.startswith("baslip: ") for line in proc.stderr.splitlines()) == 1  # two workers, one line


def test_default_output_folder_is_results_name(tmp_path):
    problem = tmp_path / "p.yaml"
    problem.write_text((ROOT / "problems" / "upward.yaml").read_text().replace("name: upward", "name: up_copy"))
    proc = run_cli(problem, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert json.loads((tmp_path / "results" / "up_copy" / "result.json").read_text())["status"] == "converged"


def test_solver_failure_exits_1_with_status_failed(tmp_path):
    problem = tmp_path / "short.yaml"
    text = (ROOT / "problems" / "downward.yaml").read_text().replace("max_iter: 300", "max_iter: 1")
    problem.write_text(text)
    assert main([str(problem), "--out", str(tmp_path / "out"), "--quiet"]) == 1
    record = json.loads((tmp_path / "out" / "result.json").read_text())
    assert record["status"] == "failed" and record["solver"]["return_status"] == "Maximum_Iterations_Exceeded"
    assert record["eigenvalues"] is None and record["stable"] is None


BAD_INPUTS = {
    "unknown_key": ("name: x\nspeed: 3\n", "speed"),
    "wrong_type": ("fix: {z: high}\n", "fix.z"),
    "nan": ("fix: {z: .nan}\n", "fix.z"),
    "inf": ("guess: {Kp: .inf}\n", "guess.Kp"),
    "mass": ("params: {m: 0}\n", "params.m"),
    "inertia": ("params: {I: -1}\n", "params.I"),
    "stiffness": ("params: {k: 0}\n", "params.k"),
    "rest_length": ("params: {rho0: 0}\n", "params.rho0"),
    "gravity": ("params: {g: -9.81}\n", "params.g"),
    "foot_below_ground": ("fix: {z: 0.1}\nguess: {theta_td: \"6 deg\"}\n", "fix.z"),
    "fixed_outside_bounds": ("fix: {z: 0.9}\nbounds: {z: [0.3, 0.7]}\n", "fix.z"),
    "malformed": ("fix: {z: 0.4\n", "malformed YAML"),
    "energy_too_low": ("fix: {z: 0.4, ydot: 0.5, energy: 1.0}\n", "fix.energy"),
    "objective_list": ("objective: [min_torque]\n", "objective"),
}


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, case):
    text, key = BAD_INPUTS[case]
    problem = tmp_path / "bad.yaml"
    problem.write_text(text)
    out = tmp_path / "out"
    assert main([str(problem), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and key in err
    assert not out.exists()


def test_unwritable_output_folder_exits_2_before_solving(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main([str(ROOT / "problems" / "downward.yaml"), "--out", str(blocker / "sub")]) == 2
    assert capsys.readouterr().err.startswith("error: output folder")


def test_usage_errors_are_one_line(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([str(ROOT / "problems" / "downward.yaml"), "--bogus"])
    assert exit_info.value.code == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_missing_file_exits_2(tmp_path, capsys):
    assert main([str(tmp_path / "nope.yaml")]) == 2
    assert "no such problem file" in capsys.readouterr().err


def test_bad_input_from_the_shell_has_no_traceback(tmp_path):
    problem = tmp_path / "bad.yaml"
    problem.write_text("params: {m: -1}\n")
    proc = run_cli(problem, "--out", tmp_path / "out")
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "params.m" in proc.stderr and "Traceback" not in proc.stderr


def test_help_documents_the_options():
    proc = run_cli("--help")
    assert proc.returncode == 0 and "--out" in proc.stdout and "result.json" in proc.stdout


def test_continuation_with_a_switch_end_to_end(tmp_path):
    """The SLIP band's period doubling, then the two-stride branch switched from it:
    plain CSV that any reader parses, the branches and special points in result.json."""
    text = (ROOT / "problems" / "continuation_slip_attack.yaml").read_text()
    assert 'range: ["20 deg", "25 deg"]' in text
    text = text.replace('range: ["20 deg", "25 deg"]', 'range: ["20.9 deg", "21.3 deg"]')
    assert "  switch: period_doubling\n" in text
    text = text.replace("  switch: period_doubling\n", "  switch: period_doubling\n  max_points: 8\n")
    problem = tmp_path / "slip.yaml"
    problem.write_text(text)
    proc = run_cli(problem, "--out", tmp_path / "out")
    assert proc.returncode == 0, proc.stderr
    with open(tmp_path / "out" / "branch.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    header = list(rows[0])
    assert len(header) == len(set(header)) and header[:3] == ["branch", "strides", "theta_td"]
    for row in rows:
        assert all(float(row[c]) == float(row[c]) for c in header if c not in ("stable", "special"))
        assert row["stable"] in ("true", "false")
    assert {(r["branch"], r["strides"]) for r in rows} == {("0", "1"), ("1", "2")}
    summary = json.loads((tmp_path / "out" / "result.json").read_text())
    assert [b["strides"] for b in summary["branches"]] == [1, 2]
    assert summary["branches"][1]["switched_from"]["type"] == "period_doubling"
    (pd,) = [p for p in summary["special_points"] if p["type"] == "period_doubling" and p["branch"] == 0]
    assert abs(pd["theta_td"] - summary["branches"][1]["switched_from"]["theta_td"]) < 1e-12
    assert (tmp_path / "out" / "diagram.png").stat().st_size > 10_000
    assert "branch 1 (2-stride orbits, switched at the period doubling)" in proc.stdout


def test_a_re_solve_that_dies_leaves_the_earlier_result_whole(tmp_path, monkeypatch, capsys):
    out = tmp_path / "downward"
    assert main(["problems/downward.yaml", "--out", str(out), "--quiet"]) == 0
    before = {name: (out / name).read_bytes() for name in ("result.json", "multipliers.csv")}

    from baslip.gait.fixedpoint import FixedPointSolver

    def killed(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(FixedPointSolver, "solve", killed)
    assert main(["problems/downward.yaml", "--out", str(out), "--quiet"]) == 1
    assert "interrupted" in capsys.readouterr().err
    assert {name: (out / name).read_bytes() for name in before} == before


@pytest.mark.parametrize("library", ENGINE_LIBRARIES)
def test_each_cached_library_cut_short_is_rebuilt_and_the_solve_succeeds(tmp_path, library):
    """A library truncated in the cache (a full disk, a killed copy) could map and then kill
    the process with SIGBUS: its checksum fails, so the next solve rebuilds it, silently,
    and succeeds with compiled code."""
    assert main(["problems/downward.yaml", "--out", str(tmp_path / "warm"), "--quiet"]) == 0  # the cache holds all four
    cache = tmp_path / "cache"
    cache.mkdir()
    # Every cached version of the four (the one the warm solve loaded is among them; older
    # keys may linger), and every version of ``library`` cut in half. The Jacobians' library
    # is rebuilt in its thread (baslip.engine.background), and checked the same way.
    for name in ENGINE_LIBRARIES:
        for built in cache_dir().glob(f"{name}-*.so"):
            if (built.parent / f"{built.name}.sha256").exists():
                shutil.copy(built, cache / built.name)
                shutil.copy(built.parent / f"{built.name}.sha256", cache / f"{built.name}.sha256")
    whole = {path: path.read_bytes() for path in cache.glob(f"{library}-*.so")}
    for path, content in whole.items():
        path.write_bytes(content[: len(content) // 2])
    env = {**os.environ, "BASLIP_CACHE_DIR": str(cache)}
    env.pop("BASLIP_NO_COMPILE", None)
    proc = subprocess.run([sys.executable, "-m", "baslip.solve", "problems/downward.yaml", "--out", str(tmp_path / "out")],
                          cwd=ROOT, capture_output=True, text=True, timeout=900, env=env)
    assert proc.returncode == 0, proc.stderr[-800:]
    assert "virtual machine" not in proc.stderr, proc.stderr
    restored = [path for path, content in whole.items() if path.read_bytes() == content]
    built = [path for path in cache.glob(f"{library}-*.so") if path not in whole]
    # The one the solve needed was rebuilt: the same bytes again, or, where only the copy
    # at the normal level was there (cut short), one at the quick start's level (a gait
    # of one solve compiles its return maps at -O0 unless an intact tuned copy is cached).
    assert len(restored) + len(built) == 1, (restored, built)
    code = json.loads((tmp_path / "out" / "result.json").read_text())["provenance"]["code"]
    assert all(route.startswith("compiled C") for route in code.values())


def test_a_low_apex_with_no_guess_is_left_to_the_search_which_finds_a_steep_leg(tmp_path, capsys):
    """z = 0.1 m refuses the default angles (the foot below ground at the apex), but with no
    guess the angles are the search's: from the body alone it finds a verified gait there,
    the leg touching down more than 45 deg from vertical."""
    problem = tmp_path / "low.yaml"
    problem.write_text("name: low\nfix: {z: 0.1}\n")
    assert main([str(problem), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    record = json.loads((tmp_path / "out" / "result.json").read_text())
    assert record["status"] == "converged" and record["residual"] <= 1e-10
    assert record["control"]["theta_td"] > math.radians(45)
