"""Peak resident memory (and wall time) of the main commands, each in a fresh process under ``/usr/bin/time``.

    python benchmarks/memory.py                 # all three; writes the "Memory" section of BENCHMARKS.md
    python benchmarks/memory.py --only train    # one of: train, eval_bn2, bn2_reference

``bn2_reference`` trains 40 batches of one epoch (then validates and tests): the peak of a training step does not
grow with the number of steps (the heap is trimmed between epochs), so this bounds the full 30-minute run.
Needs GNU time (Debian package ``time``) and ``../shared/datasets/bandai-namco-2.zip`` for the BN-2 commands.
"""
from __future__ import annotations

import argparse
import datetime
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import write_section  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
COMMANDS = {
    "train": ["train.py"],
    "eval_bn2": ["eval.py", "ckpt_path=models/bn2_reference/model.ckpt", "data=bandai_namco"],
    "bn2_reference": ["train.py", "experiment=bn2_reference", "trainer.max_epochs=1", "+trainer.limit_train_batches=40"],
}


def measure(args: list[str], out: Path) -> tuple[float, float]:
    """``(peak RSS in GB, wall seconds)`` of ``python <args> hydra.run.dir=<out>`` (wall: quiet machine only)."""
    time_bin = shutil.which("time") or "/usr/bin/time"
    if not Path(time_bin).exists():
        raise SystemExit("benchmarks/memory.py needs GNU time: apt-get install time")
    out.mkdir(parents=True, exist_ok=True)
    report = out / "time.txt"
    cmd = [time_bin, "-f", "%M %e", "-o", str(report), sys.executable, *args, f"hydra.run.dir={out}"]
    subprocess.run(cmd, cwd=ROOT, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    kb, wall = report.read_text().split()[-2:]
    return int(kb) / 1024**2, float(wall)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=sorted(COMMANDS))
    parser.add_argument("--no-write", action="store_true", help="print only; leave BENCHMARKS.md alone")
    a = parser.parse_args()
    names = [a.only] if a.only else list(COMMANDS)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            gb, wall = measure(COMMANDS[name], Path(tmp) / name)
            cmd = "python " + " ".join(COMMANDS[name])
            rows.append(f"| `{cmd}` | {gb:.2f} GB | {wall:.0f} s |")
            print(rows[-1], flush=True)
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    body = (f"`python benchmarks/memory.py` ({datetime.date.today()}, load average at the end {load}; peak resident "
            "set size from GNU time, each command in a fresh process):\n\n| command | peak RSS | wall |\n|---|---:|---:|\n"
            + "\n".join(rows))
    if not a.no_write and not a.only:
        write_section(ROOT / "BENCHMARKS.md", "## Memory", body)


if __name__ == "__main__":
    main()
