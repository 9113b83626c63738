"""The examples of docs/*.md and README.md run as written (issue 34, item 10).

Every fenced block of a document carries a marker, an HTML comment on the line just above
its opening fence (GitHub does not show it):

``<!-- example: run -->``
    run it. ``console`` blocks: every ``$ `` command (``\\`` continues a line); its exit
    code is the one its output shows (``bench: configuration error`` 2, a last verdict
    line ``FAIL ...`` 1, else 0), and every verdict line (``PASS  ID: ...``) and criterion
    row (ending in its verdict) shown must be printed as shown, spacing aside; a line with
    ``...`` is not compared. ``sh`` blocks: every command, exit 0. ``python`` blocks: the block
    saved as a script and run, exit 0.
``<!-- example: run as root -->``
    the same, where network namespaces can be made (root); skipped elsewhere, saying so.
``<!-- example: save PATH -->``
    the block is a file the blocks after it in the same document use: written to PATH.
``<!-- example: file PATH -->``
    the block is the repository's file PATH, or a part of it, word for word.
``<!-- example: not run: REASON -->``
    a synopsis, an output, a fragment of a file, or something this machine cannot do.

The blocks of one document run in order in one scratch folder, where ``examples/``,
``test_cases/``, ``tests/``, ``models/`` and ``fmu/`` are the repository's and ``.venv``
is the interpreter's environment that runs these tests; ``bench`` and ``python`` are that
environment's (first on ``PATH``). A block without a marker fails the test: a new example
is either run or says why not.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).parent.parent.parent
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LINKED = ("examples", "test_cases", "tests", "models", "fmu")
FENCE = re.compile(r"^```(\S*)[^\n]*\n(.*?)^```[ \t]*$", re.M | re.S)
MARK = re.compile(r"<!-- example: (run as root|run|save \S+|file \S+|not run: [^\n]+?) -->[ \t]*\n$")
TIMEOUT = 600  # a hang guard, not a speed bound


@dataclass
class Block:
    doc: str
    line: int
    lang: str
    text: str
    mark: str | None

    @property
    def where(self) -> str:
        return f"{self.doc}:{self.line}"


def blocks(path: Path) -> list[Block]:
    text = path.read_text()
    out = []
    for m in FENCE.finditer(text):
        before = text[: m.start()]
        mark = MARK.search(before[-300:])
        where = str(path.relative_to(ROOT))
        out.append(Block(where, before.count("\n") + 1, m.group(1), m.group(2), mark[1] if mark else None))
    return out


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_every_block_says_whether_it_runs(doc):
    unmarked = [b.where for b in blocks(doc) if b.mark is None]
    assert not unmarked, f"blocks without an <!-- example: ... --> marker: {unmarked}"


def _file_blocks() -> list[Block]:
    return [b for d in DOCS for b in blocks(d) if b.mark and b.mark.startswith("file ")]


@pytest.mark.parametrize("block", _file_blocks(), ids=lambda b: b.where)
def test_a_block_that_shows_a_file_is_that_file(block):
    path = ROOT / block.mark.split(" ", 1)[1]
    assert path.is_file(), f"{block.where}: {path} is not shipped"
    assert block.text in path.read_text(), f"{block.where}: not in {path} word for word"


# ------------------------------------------------------------------------------ running
def _scratch(tmp_path: Path) -> tuple[Path, dict[str, str]]:
    for name in LINKED:
        (tmp_path / name).symlink_to(ROOT / name)
    venv = Path(sys.executable).parent.parent
    (tmp_path / ".venv").symlink_to(venv)
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
           "COLUMNS": "200"}
    env.pop("BENCH_TRACEBACK", None)
    return tmp_path, env


def _commands(block: Block) -> list[tuple[str, list[str]]]:
    """``(command, output lines shown after it)`` of a console or sh block."""
    out: list[tuple[str, list[str]]] = []
    lines = block.text.splitlines()
    k = 0
    while k < len(lines):
        line = lines[k]
        if block.lang == "console" and not line.startswith("$ "):
            if out:
                out[-1][1].append(line)
            k += 1
            continue
        cmd = line[2:] if block.lang == "console" else line
        while cmd.rstrip().endswith("\\") and k + 1 < len(lines):
            k += 1
            cmd = cmd.rstrip()[:-1] + " " + lines[k].strip()
        cmd = cmd.split("  #")[0].strip() if block.lang == "sh" else cmd.strip()
        if cmd:
            out.append((cmd, []))
        k += 1
    return out


def _expected_exit(shown: list[str]) -> int:
    if any(s.startswith("bench: configuration error") for s in shown):
        return 2
    verdicts = [s.split()[0] for s in shown if re.match(r"(PASS|MARGINAL|FAIL|ERROR) ", s)]
    return {"FAIL": 1, "ERROR": 3}.get(verdicts[-1], 0) if verdicts else 0


def _run_command(block: Block, cmd: str, shown: list[str], cwd: Path, env: dict[str, str]) -> None:
    p = subprocess.run(shlex.split(cmd), cwd=cwd, env=env, capture_output=True, text=True, timeout=TIMEOUT)
    text = p.stdout + p.stderr
    assert "Traceback" not in text, f"{block.where}: {cmd}\n{text}"
    assert p.returncode == _expected_exit(shown), f"{block.where}: {cmd}: exit {p.returncode}\n{text}"
    printed = {" ".join(line.split()) for line in text.splitlines()}
    for s in shown:  # the verdict lines and the criteria's rows shown (value, limit, verdict)
        if "..." not in s and re.match(r"(PASS|MARGINAL|FAIL|ERROR) |.*\s(PASS|MARGINAL|FAIL|ERROR|N/A)$", s):
            assert " ".join(s.split()) in printed, f"{block.where}: {cmd}: the document shows {s!r}\n{text}"


def _run(block: Block, cwd: Path, env: dict[str, str]) -> None:
    if block.lang == "python":  # saved as a script, as a user runs it (a campaign's workers import it again)
        script = cwd / f"example_{block.line}.py"
        script.write_text(block.text)
        p = subprocess.run([sys.executable, script.name], cwd=cwd, env=env, capture_output=True, text=True,
                           timeout=TIMEOUT)
        assert p.returncode == 0, f"{block.where}:\n{p.stdout}{p.stderr}"
        return
    assert block.lang in ("console", "sh"), f"{block.where}: cannot run a {block.lang!r} block"
    for cmd, shown in _commands(block):
        _run_command(block, cmd, shown, cwd, env)


def _runs(doc: Path) -> bool:
    return any(b.mark and (b.mark.startswith("run") or b.mark.startswith("save ")) for b in blocks(doc))


@pytest.mark.parametrize("doc", [d for d in DOCS if _runs(d)], ids=lambda p: p.name)
def test_the_examples_of_a_document_run_as_written(doc, tmp_path):
    from tests.transport import netns

    cwd, env = _scratch(tmp_path)
    ran = []
    root_reason = None
    for block in blocks(doc):
        if block.mark is None or block.mark.startswith(("not run", "file ")):
            continue
        if block.mark.startswith("save "):
            path = cwd / block.mark.split(" ", 1)[1]
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(block.text)
            continue
        if block.mark == "run as root" and (root_reason := netns.unavailable()):
            continue
        _run(block, cwd, env)
        ran.append(block.where)
    assert ran or root_reason, f"{doc.name}: nothing ran"
    if root_reason:
        pytest.skip(f"ran {ran}; the blocks run as root did not run: {root_reason}")
