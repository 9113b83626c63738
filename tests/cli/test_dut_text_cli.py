"""An in-process DUT's exception text shown by ``bench replay`` and ``bench info``: made
visible, never obeyed by the terminal (bench.textsafe)."""

from __future__ import annotations

import re
from pathlib import Path

import bench.dut.estimator as estimator
from bench.cli import main
from bench.dut.estimator import Estimator

SHORT = Path(__file__).parent.parent / "data" / "short_drive.toml"
RAW_CONTROL = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f]")  # newline and tab are the output's own


class _Hostile(Estimator):
    name = "hostile_text"

    def configure(self, config):
        pass

    def step(self, inputs):
        raise RuntimeError("\x1b]0;pwned\x07\x1b[2J filter <b>diverged</b> \x00")


def test_replay_and_info_show_a_dut_exception_with_its_control_characters_visible(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(estimator._FACTORIES, "hostile_text", _Hostile)
    rec, out, faults = tmp_path / "s.mcap", tmp_path / "r.mcap", tmp_path / "none.toml"
    faults.write_text('[[fault]]\nlayer = "wire"\ntarget = "can:ODOMETER"\nkind = "counter_skip"\n'
                      'start = "80 s"\nend = "81 s"\nparams = { skip = 2 }\n')  # replay re-encodes the samples
    assert main(["synth", str(SHORT), "-o", str(rec), "-q"]) == 0
    capsys.readouterr()
    assert main(["replay", str(rec), "-o", str(out), "--estimator", "hostile_text", "--faults", str(faults), "-q"]) == 1
    shown = capsys.readouterr()
    assert "dut_failed" in shown.out and "\\x1b]0;pwned\\x07\\x1b[2J filter" in shown.out
    assert not RAW_CONTROL.search(shown.out + shown.err)
    assert main(["info", str(out)]) == 0
    shown = capsys.readouterr()
    assert "\\x1b]0;pwned" in shown.out and not RAW_CONTROL.search(shown.out + shown.err)
