"""The figure of docs/blender.md's "The animator's loop": a Bandai-Namco-2 walk keyed every 30 frames, filled in real
Blender with the contact model (models/bn2_v2, exported for the extension); one generated key lifted by hand and the
fill run again.

    python benchmarks/blender_loop_figure.py [--data ../shared/datasets/bandai-namco-2.zip]

Writes docs/blender/loop.png: the left knee's curve after the first fill and after the second (the edit kept as a
key, the gaps re-filled shaded, the gap kept plain), each gap's network share and the planted feet the Last Fill
panel lists.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import tempfile
import zipfile
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

ROOT = Path(__file__).resolve().parents[1]
CLIP = "Bandai-Namco-Research-Motiondataset-2/data/dataset-2_walk-turn-right_active_026.bvh"
CHANNEL = ['pose.bones["LowerLeg_L"].rotation_euler', 0]
EDIT = (75, 25.0)  # frame, degrees


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=os.environ.get("BANDAI_NAMCO_PATH",
                                                     str(ROOT.parent / "shared" / "datasets" / "bandai-namco-2.zip")))
    args = ap.parse_args()
    from inbetweening.blender.bpyenv import bpy_python
    from inbetweening.blender.build import DEFAULT_CKPTS, build, export

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (zip_path,) = build(tmp / "dist", [ROOT / c for c in DEFAULT_CKPTS], platforms=["linux-x64"], log=lambda *a: None)
        export(ROOT / "models" / "bn2_v2" / "model.ckpt", tmp / "v2.onnx")
        with zipfile.ZipFile(args.data) as zf:
            (tmp / "clip.bvh").write_bytes(zf.read(CLIP))
        cfg = {"zip": str(zip_path), "bvh": str(tmp / "clip.bvh"), "model_path": str(tmp / "v2.onnx"), "every": 30,
               "frames": 121, "channel": CHANNEL, "edit": EDIT, "out": str(tmp / "loop.json")}
        (tmp / "cfg.json").write_text(json.dumps(cfg))
        env = {**os.environ, "BLENDER_USER_RESOURCES": str(tmp / "user"), "OMP_NUM_THREADS": "1"}
        subprocess.run([str(bpy_python()), str(ROOT / "benchmarks" / "blender" / "bpy_loop_figure.py"),
                        str(tmp / "cfg.json")], check=True, env=env, capture_output=True)
        d = json.loads((tmp / "loop.json").read_text())
    grid, keys = np.array(d["grid"]), d["keys"]
    first, second = d["runs"]
    deg = 180 / np.pi
    fig = Figure(figsize=(10, 5.2), dpi=100)
    FigureCanvasAgg(fig)
    ax, feet = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3.2, 1]})
    refilled = {tuple(g) for g in second["refilled"]}
    top = max(np.max(first["curve"]), np.max(second["curve"])) * deg
    for (a, b), info in zip(second["gaps"], second["info"]):
        again = (a, b) in refilled
        if again:
            ax.axvspan(a, b, color="tab:green", alpha=0.08, lw=0)
        share = " / ".join(f"{100 * w:.0f} %" for _, _, w in info["windows"])
        ax.text((a + b) / 2, top + 4, f"{a}–{b}\nnetwork {share}\n{'re-filled' if again else 'kept'}",
                ha="center", va="bottom", fontsize=7.5, color="tab:green" if again else "0.35")
        for row, side in enumerate(("L", "R")):
            for s, e in (info["planted"] or {}).get(side, []):
                feet.broken_barh([(s - 0.5, e - s + 1)], (1 - row - 0.35, 0.7), color="tab:brown", alpha=0.8)
    ax.plot(grid, np.array(d["truth"]) * deg, color="0.75", lw=2.5, label="original clip")
    ax.plot(grid, np.array(first["curve"]) * deg, "--", color="tab:blue", lw=1.4, label="first fill")
    ax.plot(grid, np.array(second["curve"]) * deg, color="tab:green", lw=1.6, label="after the edit, filled again")
    on_key = np.isin(grid, keys)
    ax.plot(grid[on_key], np.array(second["curve"])[on_key] * deg, "o", color="tab:red", ms=7, label="your keys")
    at = np.isclose(grid, EDIT[0])
    ax.plot(grid[at], np.array(second["curve"])[at] * deg, "*", color="tab:orange", ms=15,
            label=f"a generated key you lifted by {EDIT[1]:.0f}° (now a Keyframe: kept)")
    ax.set_ylabel(f"{CHANNEL[0].split(chr(34))[1]} X rotation\ndegrees", fontsize=8)
    low = min(np.min(first["curve"]), np.min(second["curve"]), np.min(d["truth"])) * deg
    ax.set_ylim(low - 22, top + 28)
    ax.legend(fontsize=7.5, loc="lower center", ncol=3)
    ax.grid(alpha=0.3)
    feet.set_yticks([1, 0], ["left foot", "right foot"], fontsize=8)
    feet.set_ylim(-0.6, 1.6)
    feet.set_xlabel("frame")
    feet.set_title("planted (predicted contact > 0.5, the Last Fill panel's 'feet planted')", fontsize=8)
    feet.grid(alpha=0.3, axis="x")
    fig.suptitle(f"{Path(CLIP).name} in Blender, models/bn2_v2, keys every 30 frames: fill, edit, fill again",
                 fontsize=10)
    fig.tight_layout()
    out = ROOT / "docs" / "blender" / "loop.png"
    fig.savefig(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
