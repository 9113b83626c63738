"""`bench info` on a recording with a flipped chunk names the damaged chunk and shows the
rest (it used to crash with the mcap library's CRC error)."""

import json
from pathlib import Path

from bench.cli import main
from bench.record.scan import scan

SHORT = Path(__file__).parent.parent / "data" / "short_drive.toml"


def test_info_names_the_damaged_chunk_and_shows_the_rest(tmp_path, capsys):
    rec = tmp_path / "s.mcap"
    assert main(["synth", str(SHORT), "-o", str(rec), "-q"]) == 0
    idx = scan(rec)
    n = len(idx.chunks)
    c = idx.chunks[n // 2]
    idx.close()
    data = bytearray(rec.read_bytes())
    for k in range(c.offset + c.length // 2, c.offset + c.length // 2 + 64):
        data[k] ^= 0xFF
    rec.write_bytes(bytes(data))
    capsys.readouterr()
    assert main(["info", str(rec)]) == 0
    out = capsys.readouterr().out
    assert "DAMAGED: 1 stretch(es) could not be read and were skipped" in out
    line = next(x for x in out.splitlines() if x.startswith("  damaged:"))
    assert f"chunk {n // 2} at byte {c.offset} ({c.length} B), messages logged at bench time" in line
    assert "/imu" in line and "CRC mismatch" in line
    assert "ended: complete" in out and "/foxglove/truth/pose" in out  # the rest is shown
    assert main(["info", str(rec), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    (dmg,) = d["damage"]
    assert (dmg["chunk"], dmg["offset"], dmg["length"]) == (n // 2, c.offset, c.length)
    assert 0 < d["topics"]["/imu"]["samples"] < 18000 and d["finished"]
