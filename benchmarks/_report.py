"""Shared helper of the benchmark scripts: write one section of BENCHMARKS.md, keeping the others."""
from __future__ import annotations

import argparse
import json
import os
import re
import sys
from pathlib import Path

BN2 = Path(__file__).resolve().parents[2] / "shared" / "datasets" / "bandai-namco-2.zip"


def write_section(path: Path, section: str, body: str) -> None:
    """Add or replace the ``section`` heading (e.g. ``## Inference latency``) of ``path``; re-reads the file now."""
    text = path.read_text() if path.exists() else "# Benchmarks\n"
    block = f"{section}\n\n{body.strip()}\n"
    pattern = re.compile(rf"^{re.escape(section)}[ \t]*\n.*?(?=^## |\Z)", re.MULTILINE | re.DOTALL)
    if pattern.search(text):
        text = pattern.sub(lambda _: block + "\n", text, count=1)
    else:
        text = text.rstrip("\n") + "\n\n" + block
    path.write_text(text.rstrip("\n") + "\n")


def publish(text: str, section: str, write: bool, path: Path | None = None) -> None:
    """Print a benchmark's section and, when ``write``, put it into BENCHMARKS.md (or ``path``)."""
    print(text)
    if write:
        path = path or Path(__file__).resolve().parents[1] / "BENCHMARKS.md"
        write_section(path, section, text)
        print(f"\nwrote the '{section}' section of {path.name}")


def save_json(out: str | Path, script: str, argv, **data) -> None:
    """Write a benchmark's results as JSON to ``out`` with the command that made them (``python benchmarks/<script>``
    and its arguments)."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    args = " ".join(argv if argv is not None else sys.argv[1:])
    out.write_text(json.dumps(dict(command=f"python benchmarks/{script} {args}".strip(), **data), indent=1))


def ratio_of(rows, error: str = "error", base: str = "interpolation") -> float:
    """The pooled ratio of ``rows``: their summed ``error`` over their summed ``base``."""
    return sum(r[error] for r in rows) / sum(r[base] for r in rows)


def strip_arguments(ap: argparse.ArgumentParser, clip: str, out: str, clip_help: str) -> None:
    """The arguments of a picture of one clip filled from keys (``unseen_strip``, ``foot_lock_strip``): the checkpoint,
    the clip, the key interval, the frames drawn, the output and the Bandai-Namco-2 zip."""
    ap.add_argument("ckpt")
    ap.add_argument("--clip", default=clip, help=clip_help)
    ap.add_argument("--every", type=int, default=30, help="a keyframe every N frames")
    ap.add_argument("--frames", type=int, default=91, help="frames used (from the clip's start)")
    ap.add_argument("--out", default=out, help="output path")
    ap.add_argument("--data", default=os.environ.get("BANDAI_NAMCO_PATH", str(BN2)),
                    help="Bandai-Namco-2 zip or folder (default: $BANDAI_NAMCO_PATH, else ../shared/datasets)")
