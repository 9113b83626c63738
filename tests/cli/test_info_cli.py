import json
from pathlib import Path

from bench.cli import main

SHORT = Path(__file__).parent.parent / "data" / "short_drive.toml"


def test_info_of_a_finished_and_a_truncated_recording(tmp_path, capsys):
    rec = tmp_path / "s.mcap"
    assert main(["synth", str(SHORT), "-o", str(rec), "-q"]) == 0
    capsys.readouterr()
    assert main(["info", str(rec)]) == 0
    out = capsys.readouterr().out
    assert "ended: complete" in out and "/imu/ideal" in out and "18000" in out
    assert main(["info", str(rec), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["topics"]["/truth"]["samples"] == 9001 and d["span_s"] == [0.0, 90.0]
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(rec.read_bytes()[: rec.stat().st_size * 2 // 3])
    assert main(["info", str(cut), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert not d["complete"] and d["ended"]["status"] == "unfinished"
    assert 0 < d["topics"]["/imu"]["samples"] < 18000
    assert main(["info", str(tmp_path / "none.mcap")]) == 2  # usage: no such file
