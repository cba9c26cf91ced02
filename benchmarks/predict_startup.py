"""Wall and CPU time of ``python -m inbetweening.predict`` (no render) on a 121-frame clip with 5 keyframes, start-up
included: the default (the shipped ensemble's window graphs on ONNX Runtime, no PyTorch) against the same three
models from their checkpoints (PyTorch).

    python benchmarks/predict_startup.py [--path ../shared/datasets/bandai-namco-2.zip] [--rounds 5] [--no-write]

The clip is the first 121 frames of a Bandai-Namco-2 take (keyframes 0, 30, 60, 90, 120: four 29-frame gaps).  Each
round runs, as fresh processes: the CLI with its default models, the CLI with ``ckpt_path=`` the shipped
checkpoints, ``python -c "import torch"`` (the floor any PyTorch inference pays) and ``python -c "pass"``.
Reported: the median wall and CPU (user + system) time of each, after one warm-up round, the bytecode cached as an
installed package has it (``PYTHONDONTWRITEBYTECODE`` removed from the runs' environment).  Written as the section
"## predict start-up" of BENCHMARKS.md (date, command, load average).  Target (issue 54): the default at most 1 s on
the quiet machine.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import _report  # noqa: E402  (benchmarks/ helper)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
from inbetweening.api.shipped import SHIPPED_CKPTS  # noqa: E402

SECTION = "## predict start-up"
KEYS = "[0,30,60,90,120]"


def cut_clip(zip_path: str, out: Path, frames: int = 121) -> str:
    """Write the first ``frames`` frames of the first member with enough frames; returns the member's name."""
    with zipfile.ZipFile(zip_path) as zf:
        for info in sorted(zf.infolist(), key=lambda i: i.filename):
            if not info.filename.lower().endswith(".bvh") or info.filename.startswith("__MACOSX/"):
                continue
            head, motion = zf.read(info).decode().split("MOTION", 1)
            lines = motion.strip().splitlines()
            if int(lines[0].split()[-1]) < frames:
                continue
            out.write_text(f"{head}MOTION\nFrames: {frames}\n{lines[1]}\n" + "\n".join(lines[2 : 2 + frames]) + "\n")
            return info.filename.rsplit("/", 1)[-1]
    raise SystemExit(f"no clip of {frames} frames in {zip_path}")


# as an installed package runs: its bytecode cached (a machine with PYTHONDONTWRITEBYTECODE=1 compiles every module
# at every start: 0.14-0.55 s of predict's, measured on the dev machine, where it is set)
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def timed(cmd: list[str], cwd: Path) -> tuple[float, float]:
    """Wall and CPU (user + system) seconds of ``cmd`` run as a fresh process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, check=False, env=ENV)
    dt = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{r.stderr}")
    return dt, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


ROWS = {  # key: what the table calls it
    "default": "`python -m inbetweening.predict input=clip.bvh keyframes=KEYS output=out.bvh` (the default: the shipped "
               "three's `model.onnx` on ONNX Runtime; start-up, read, load, fill 116 frames, write)",
    "ckpt": "the same with `ckpt_path=` the three's `model.ckpt` (PyTorch)",
    "torch": '`python -c "import torch"`',
    "python": '`python -c "pass"`',
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--path", default=str(ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip"))
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    py = sys.executable
    ckpts = "[" + ",".join(str(ROOT / c) for c in SHIPPED_CKPTS) + "]"
    load0 = os.getloadavg()[0]
    cli = [py, "-m", "inbetweening.predict", "input=clip.bvh", f"keyframes={KEYS}", "output=out.bvh"]
    cmds = {"default": cli, "ckpt": [*cli, f"ckpt_path={ckpts}"], "torch": [py, "-c", "import torch"],
            "python": [py, "-c", "pass"]}
    times: dict[str, list[tuple[float, float]]] = {k: [] for k in cmds}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        source = cut_clip(args.path, tmp / "clip.bvh")
        for cmd in cmds.values():  # a warm-up, not counted: the bytecode written, the files in the page cache
            timed(cmd, tmp)
        for _ in range(args.rounds):  # interleaved: a load change touches every row alike
            for k, cmd in cmds.items():
                times[k].append(timed(cmd, tmp))
    load1 = os.getloadavg()[0]
    med = {k: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v)) for k, v in times.items()}
    cmd = "python -m benchmarks run predict_startup" + (f" --rounds {args.rounds}" if args.rounds != 5 else "")
    quiet = "quiet" if max(load0, load1) < 1.2 else "the machine was **shared**: compare CPU times"
    rows = [f"| {ROWS[k].replace('KEYS', KEYS)} | {'**' if k == 'default' else ''}{med[k][0]:.2f} s"
            f"{'**' if k == 'default' else ''} | {med[k][1]:.2f} s | {', '.join(f'{w:.2f}' for w, _ in times[k])} |"
            for k in cmds]
    text = "\n".join([
        f"Date: {_dt.date.today().isoformat()}; command: `{cmd}`; 2-core AMD EPYC dev machine; 1-min load average "
        f"{load0:.2f} at the start, {load1:.2f} at the end ({quiet}). "
        f"Clip: the first 121 frames of `{source}`, keyframes {KEYS}, no render; {args.rounds} rounds, interleaved.",
        "",
        "| fresh process | median wall | median CPU | wall per round |",
        "|---|---:|---:|---|",
        *rows,
        "",
        f"The default takes {med['default'][0] / med['ckpt'][0]:.2f}× the wall time of the same fill from the "
        f"checkpoints (CPU {med['default'][1] / med['ckpt'][1]:.2f}×): it imports neither PyTorch nor the training, "
        "config or plotting stack (`tests/test_startup.py`), and its sessions start without ONNX Runtime's graph "
        "optimisations (`runtime/onnx_backend.py`) on graphs saved with the basic ones applied (`api/export.py`). "
        "Target: at most 1 s on the quiet machine.",
    ])
    _report.publish(text, SECTION, not args.no_write)


if __name__ == "__main__":
    main()
