"""The note naming the processes a DUT left running (bench/scoring/leftovers.py): read
from an external DUT's ``dut_exit`` and a batch DUT's ``run_start``; a note, never an
issue (the verdict is the DUT output's)."""

from __future__ import annotations

import json

from bench.scoring.data import RunData
from bench.scoring.integrity import check_integrity
from bench.scoring.leftovers import left_running_notes


def _left(*pids: int) -> str:
    return json.dumps([{"pid": p, "command": f"sleep {p}", "ended": "ended on SIGTERM"} for p in pids])


def test_none_left_no_note():
    assert left_running_notes({}, {}) == []
    assert left_running_notes({"dut_left_running": "[]"}, {"left_running": "[]"}) == []


def test_each_process_is_named_with_its_command_line_and_how_it_ended():
    (note,) = left_running_notes({}, {"left_running": _left(41, 42)})
    assert note.startswith("the DUT left 2 processes running when it ended, killed by the bench")
    assert "pid 41 `sleep 41` (ended on SIGTERM); pid 42 `sleep 42` (ended on SIGTERM)" in note
    (note,) = left_running_notes({"dut_left_running": _left(7)}, {})  # a batch DUT's
    assert note.startswith("the DUT left 1 process running") and "pid 7 `sleep 7`" in note


def test_many_are_counted_past_five():
    (note,) = left_running_notes({}, {"left_running": _left(*range(1, 9))})
    assert "pid 5 " in note and "pid 6 " not in note and note.endswith("; and 3 more")


def test_a_record_that_does_not_parse_is_said_so():
    (note,) = left_running_notes({"dut_left_running": "[{"}, {})
    assert "run_start dut_left_running does not parse" in note
    (note,) = left_running_notes({}, {"left_running": '{"pid": 1}'})
    assert "dut_exit left_running is not a list" in note


def test_it_is_a_note_not_an_issue():
    run = RunData(path=None, run_start={"dut_left_running": _left(9)}, run_end={"status": "complete"})  # type: ignore[arg-type]
    integ = check_integrity(run)
    assert any("pid 9 `sleep 9`" in n for n in integ.notes)
    assert not any("pid 9" in i for i in integ.bench + integ.dut)
