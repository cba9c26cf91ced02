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


def test_gpu_pieces_round_trip(tmp_path):
    """benchmarks/gpu_pack.py cuts the dataset's two archives into pieces, one per call; v3_gpu.sh's ``take``, called
    once per piece from a tree holding only that piece (as each call to the GPU machine is), keeps them and, with the
    last, puts the archives together, checks them and unpacks every BVH file as it was, with the manifest; a piece from
    another pack is refused."""
    import hashlib
    import random
    import zipfile

    rng = random.Random(0)
    pfx = "Bandai-Namco-Research-Motiondataset-2/data/"
    files = {f"dataset-2_walk_normal_{i:03d}.bvh": "".join(rng.choice("0123456789. -\n") for _ in range(3000)).encode()
             for i in range(5)}
    src = tmp_path / "bn2.zip"
    with zipfile.ZipFile(src, "w") as z:
        for name, data in files.items():
            z.writestr(pfx + name, data)
            z.writestr(pfx + name.replace(".bvh", ".json"), b"{}")  # not read by the loader: stays behind
    pack = tmp_path / "pack"
    run = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "gpu_pack.py"), "--zip", str(src), "--out", str(pack),
                          "--piece", "0.004"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    pieces = sorted(pack.glob("c*"), key=lambda p: int(p.name[1:]))
    assert len(pieces) >= 2
    env = {**os.environ, "OUT": str(tmp_path / "out"), "PIECES": str(tmp_path / "kept"), "BN": str(tmp_path / "bn"),
           "PY": sys.executable}
    for k, piece in enumerate(pieces):
        call = tmp_path / f"call{k}"
        (call / ".gpu").mkdir(parents=True)
        (call / ".gpu" / piece.name).symlink_to(piece, target_is_directory=True)
        res = subprocess.run(["bash", str(ROOT / "benchmarks" / "v3_gpu.sh"), "take"], cwd=call, env=env,
                             capture_output=True, text=True, timeout=300)
        assert res.returncode == 0, res.stdout + res.stderr
        last = k == len(pieces) - 1
        assert ("put together, 2 archives checked and unpacked" in res.stdout) == last, res.stdout
    data = tmp_path / "bn" / pfx
    assert {p.name: p.read_bytes() for p in data.iterdir()} == files
    manifest = [line.split("\t") for line in (tmp_path / "bn" / "bn2_manifest.tsv").read_text().splitlines()]
    assert {n: (int(s), h) for n, s, h in manifest} == {n: (len(d), hashlib.sha1(d).hexdigest()) for n, d in files.items()}

    # a piece changed on the way: the archive it belongs to is refused, nothing claimed unpacked
    bad = tmp_path / "bad"
    (bad / ".gpu").mkdir(parents=True)
    for piece in pieces:
        (bad / ".gpu" / piece.name).mkdir()
        for f in piece.iterdir():
            (bad / ".gpu" / piece.name / f.name).write_bytes(f.read_bytes())
    blob = bad / ".gpu" / pieces[0].name / f"bn2.{pieces[0].name[1:]}"
    blob.write_bytes(b"x" + blob.read_bytes()[1:])
    res = subprocess.run(["bash", str(ROOT / "benchmarks" / "v3_gpu.sh"), "take"], cwd=bad,
                         env={**env, "PIECES": str(tmp_path / "kept2"), "BN": str(tmp_path / "bn2")},
                         capture_output=True, text=True, timeout=300)
    assert res.returncode != 0 and "its sha1 is not the packed one" in res.stdout + res.stderr


def test_body_parts_split_a_humanoid_into_legs_arms_and_trunk():
    """``body_parts``' grouping on Bandai-Namco-2's joints, the expected groups written out by name."""
    from types import SimpleNamespace

    from benchmarks.body_parts import body_parts

    names = ("Hips Spine Chest Neck Head Shoulder_L UpperArm_L LowerArm_L Hand_L Shoulder_R UpperArm_R LowerArm_R Hand_R "
             "UpperLeg_L LowerLeg_L Foot_L Toes_L UpperLeg_R LowerLeg_R Foot_R Toes_R").split()
    parents = [-1, 0, 1, 2, 3, 2, 5, 6, 7, 2, 9, 10, 11, 0, 13, 14, 15, 0, 17, 18, 19]
    parts = body_parts(SimpleNamespace(names=names, parents=parents), [15, 16, 19, 20])
    got = {k: {names[i] for i in v} for k, v in parts.items()}
    assert got["legs"] == {n for n in names if "Leg" in n or "Foot" in n or "Toes" in n}
    assert got["arms"] == {n for n in names if "Arm" in n or "Hand" in n or "Shoulder" in n}
    assert got["trunk and head"] == {"Hips", "Spine", "Chest", "Neck", "Head"}
