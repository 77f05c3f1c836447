"""Specification of baslip.studies.controllers, the parts its study tests do not reach: a
controllers study is heard from while its batches run."""

import types

import numpy as np
from fakeclock import collect_in_thread

from baslip import diagnostics
from baslip.model.dynamics import APEX
from baslip.model.hiplaw import PD
from baslip.studies import controllers
from baslip.studies.progress import Progress
from baslip.studies.runner import ResumableCsv


def _slow_lockstep(rmap, params, controller, starts, X, strides, tolerance, settle):
    """In place of the batched closed-loop runs: 45 s on the fake clock, every run converged."""
    diagnostics.CLOCK.advance(45.0)
    return [types.SimpleNamespace(outcome="converged", strides_run=strides, strides_to_converge=3, final_eps=1e-12)
            for _ in starts]


def test_a_controllers_study_says_what_its_batch_does_and_is_heard_from_every_10_s(monkeypatch, tmp_path,
                                                                                    fake_clock):
    monkeypatch.setattr(controllers, "make_controller", lambda name, context, rmap: None)
    monkeypatch.setattr(controllers, "run_closed_loop_many", _slow_lockstep)
    tasks = [{"task": k, "controller": name, **{f"d_{n}": 0.0 for n in APEX.names}}
             for k, name in enumerate(["constant", "constant", "feedback"])]
    context = {"law": PD, "X": np.array([0.4, -1.5, 0.5, 0.0]), "params": None, "strides": 10, "tolerance": 1e-8,
               "settle": 1}
    for shown in (True, False):
        clock = fake_clock(shown)
        table = ResumableCsv(tmp_path / f"controllers_{shown}.csv", ["task", "outcome"], ["task"])
        ran = collect_in_thread(controllers.controllers_worker, tasks, context, Progress("controllers", 3, not shown),
                                table)
        assert ran == (3, False, "") and clock.time == 90.0 and clock.running() == 0
        if not shown:
            assert clock.said == []
            continue
        said = clock.messages()
        assert "controller constant: 2 runs in lockstep" in said and "controller feedback: 1 run in lockstep" in said
        assert "controllers: 0/3 done, 36 s so far, tasks running" in said
        assert clock.longest_silence(0.0, 90.0) <= 10.0
