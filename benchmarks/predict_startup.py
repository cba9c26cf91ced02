"""Wall time of ``python -m inbetweening.predict`` (no render) on a 121-frame clip with 5 keyframes, start-up included.

    python benchmarks/predict_startup.py [--path ../shared/datasets/bandai-namco-2.zip] [--rounds 3] [--no-write]

The clip is the first 121 frames of a Bandai-Namco-2 take (keyframes 0, 30, 60, 90, 120: four 29-frame gaps),
filled by the shipped model ``models/bn2_reference``.  Each round runs, as fresh processes: the CLI itself,
``python -c "import torch"`` (the floor any PyTorch inference pays) and ``python -c "pass"``.  Reported: the
median wall time of each and the ratio CLI / ``import torch`` within the run.  Written as the section
"## predict start-up" of BENCHMARKS.md (date, command, load average).
"""
from __future__ import annotations

import argparse
import datetime as _dt
import os
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import _report  # noqa: E402  (benchmarks/ helper)

ROOT = Path(__file__).resolve().parents[1]
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


def wall(cmd: list[str], cwd: Path) -> float:
    t = time.perf_counter()
    r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, check=False)
    dt = time.perf_counter() - t
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{r.stderr}")
    return dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--path", default=str(ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip"))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    py = sys.executable
    ckpt = ROOT / "models" / "bn2_reference" / "model.ckpt"
    load0 = os.getloadavg()[0]
    times: dict[str, list[float]] = {"predict": [], "torch": [], "python": []}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        source = cut_clip(args.path, tmp / "clip.bvh")
        cli = [py, "-m", "inbetweening.predict", f"ckpt_path={ckpt}", "input=clip.bvh", f"keyframes={KEYS}",
               "output=out.bvh"]
        for _ in range(args.rounds):
            times["predict"].append(wall(cli, tmp))
            times["torch"].append(wall([py, "-c", "import torch"], tmp))
            times["python"].append(wall([py, "-c", "pass"], tmp))
    load1 = os.getloadavg()[0]
    med = {k: statistics.median(v) for k, v in times.items()}
    cmd = "python benchmarks/predict_startup.py" + (f" --rounds {args.rounds}" if args.rounds != 3 else "")
    quiet = "quiet" if max(load0, load1) < 1.2 else "the machine was **shared**"
    text = "\n".join([
        f"Date: {_dt.date.today().isoformat()}; command: `{cmd}`; 2-core AMD EPYC dev machine; 1-min load average "
        f"{load0:.2f} at the start, {load1:.2f} at the end ({quiet}; the ratio is within the run). "
        f"Clip: the first 121 frames of `{source}`, keyframes {KEYS}, shipped model `models/bn2_reference`, no render.",
        "",
        "| fresh process | median wall time | rounds |",
        "|---|---:|---|",
        f"| `python -m inbetweening.predict ... keyframes={KEYS}` (start-up, read, load, fill 116 frames, write) | "
        f"**{med['predict']:.2f} s** | {', '.join(f'{t:.2f}' for t in times['predict'])} |",
        f"| `python -c \"import torch\"` | {med['torch']:.2f} s | {', '.join(f'{t:.2f}' for t in times['torch'])} |",
        f"| `python -c \"pass\"` | {med['python']:.2f} s | {', '.join(f'{t:.2f}' for t in times['python'])} |",
        "",
        f"Within this run the CLI takes {med['predict'] / med['torch']:.2f}× the bare `import torch`, i.e. "
        f"{med['predict'] - med['torch']:.2f} s on top of it.  Without a render the CLI imports no Lightning, Hydra, "
        "OmegaConf, matplotlib or roma (`tests/test_startup.py`); `--help` and a missing input answer before torch is "
        "imported.",
    ])
    _report.publish(text, SECTION, not args.no_write)


if __name__ == "__main__":
    main()
