"""``python -m benchmarks`` (benchmarks/__main__.py, benchmarks/registry.py): every script of benchmarks/ is a named
benchmark or a step of one, every benchmark's script is there and starts (its usage), and the tool's errors are one
line with exit status 2."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.__main__ import main  # noqa: E402
from benchmarks.registry import BENCHMARKS, BY_NAME  # noqa: E402

TOOL = {"__init__.py", "__main__.py", "registry.py", "_report.py"}  # the tool itself and the scripts' shared helper


def tool(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "benchmarks", *args], cwd=ROOT, capture_output=True, text=True,
                          env={**os.environ, "PYTHONPATH": str(ROOT / "src")}, timeout=300)


def test_every_script_is_a_benchmark_or_a_step_of_one():
    scripts = {f.name for f in (ROOT / "benchmarks").iterdir() if f.suffix in (".py", ".sh")} - TOOL
    named = {b.script for b in BENCHMARKS} | {s for b in BENCHMARKS for s in b.steps}
    assert scripts - named == set(), "scripts of benchmarks/ no benchmark names"
    assert named - scripts == set(), "benchmarks whose script is missing"
    assert len(BY_NAME) == len(BENCHMARKS), "two benchmarks share a name"


def test_a_benchmark_runs_its_steps_itself():
    for b in BENCHMARKS:
        for step in b.steps:
            assert f"benchmarks/{step}" in b.path.read_text(), f"{b.script} does not run {step}"


def test_nothing_but_results_under_results():
    assert not [f for f in (ROOT / "results").rglob("*") if f.suffix in (".py", ".sh")]


def test_list_names_every_benchmark_with_its_time_and_section(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out.splitlines()
    for b in BENCHMARKS:
        row = next(line for line in out if line.split()[0] == b.name)
        assert b.time in row and b.cited in row


def test_show_gives_the_command_and_what_it_writes(capsys):
    assert main(["show", "folds"]) == 0
    out = capsys.readouterr().out
    assert "python -m benchmarks run folds <out dir> <name>" in out and "benchmarks/folds.sh" in out


@pytest.mark.parametrize("args, says", [(["run", "nope"], "no benchmark named 'nope'"), (["frobnicate"], "unknown"),
                                        (["run"], "name a benchmark")])
def test_bad_input_is_one_line_and_status_2(capsys, args, says):
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("bench", [b for b in BENCHMARKS if b.script.endswith(".sh")], ids=lambda b: b.name)
def test_shell_benchmarks_parse(bench):
    assert subprocess.run(["bash", "-n", str(bench.path)], capture_output=True).returncode == 0


@pytest.mark.slow
@pytest.mark.parametrize("bench", [b for b in BENCHMARKS if b.script.endswith(".py")], ids=lambda b: b.name)
def test_python_benchmarks_start(bench):
    """Each one starts through the tool: its imports resolve and it prints its usage."""
    r = tool("run", bench.name, "--help")
    assert r.returncode == 0, r.stderr[-2000:]
    assert "usage:" in r.stdout


@pytest.mark.slow
@pytest.mark.parametrize("bench", [b for b in BENCHMARKS if b.script.endswith(".sh") and b.usage.startswith("<")],
                         ids=lambda b: b.name)
def test_shell_benchmarks_start_and_ask_for_their_arguments(bench):
    """Started without its arguments, each stops at its first required argument, naming it (``${1:?out dir}``)."""
    r = tool("run", bench.name)
    assert r.returncode != 0
    first = bench.usage.split()[0].strip("<>")
    assert f"{bench.script}: line" in r.stderr and first.split("|")[0].split("=")[0] in r.stderr, r.stderr[-2000:]
