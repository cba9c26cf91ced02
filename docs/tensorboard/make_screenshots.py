"""Re-draw what TensorBoard serves for a log folder as small PNGs (docs/tensorboard.md).

No headless browser is available on this project's machines, so these are not browser screenshots: the script
starts TensorBoard on 127.0.0.1, reads the same HTTP API the web page reads (scalar series, the HParams session
groups with their default columns, the logged images) and draws that with matplotlib.

    python docs/tensorboard/make_screenshots.py <logdir> [--out docs/tensorboard]
"""
from __future__ import annotations

import argparse
import io
import json
import socket
import subprocess
import sys
import time
import urllib.parse
import urllib.request
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from PIL import Image


def get(port: int, path: str, body: dict | None = None, raw: bool = False):
    req = urllib.request.Request(f"http://127.0.0.1:{port}{path}", headers={"Content-Type": "application/json"},
                                 data=None if body is None else json.dumps(body).encode())
    with urllib.request.urlopen(req, timeout=60) as r:
        data = r.read()
    return data if raw else json.loads(data)


def start(logdir: str) -> tuple[subprocess.Popen, int]:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    tb = subprocess.Popen([sys.executable, "-m", "tensorboard.main", "--logdir", logdir, "--host", "127.0.0.1",
                           "--port", str(port), "--load_fast=true"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    for _ in range(120):
        try:
            if get(port, "/data/runs"):
                time.sleep(3)  # let the data server finish its first load
                return tb, port
        except OSError:
            pass
        time.sleep(1)
    tb.terminate()
    raise RuntimeError("TensorBoard did not start")


def save(fig: Figure, path: Path) -> None:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=fig.dpi)
    Image.open(buf).convert("P", palette=Image.ADAPTIVE, colors=128).save(path, optimize=True)
    print(path, path.stat().st_size, "bytes")


def landing(port: int, out: Path) -> None:
    """The Time Series landing page: the groups in the page's order, first charts of each, every run."""
    tags = get(port, "/data/plugin/scalars/tags")
    runs = sorted(tags)
    groups: dict[str, list[str]] = {}
    for t in sorted({t for r in runs for t in tags[r]}):
        groups.setdefault(t.split("/")[0], []).append(t)
    pick = {"test": ["test/l2p@15", "test/l2p_ratio@15", "test/l2p@45", "test/l2p_ratio@45"],
            "train": ["train/loss", "train/lr", "train/windows_per_s", "train/grad_norm"],
            "val": ["val/l2p@15", "val/l2p_ratio@15", "val/l2p@45", "val/l2p_mean_best"]}
    fig = Figure(figsize=(11, 6.6), dpi=80)
    FigureCanvasAgg(fig)
    names = sorted(groups)
    colours = dict(zip(runs, ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple"]))
    for row, g in enumerate(names):
        for col, tag in enumerate(pick.get(g, groups[g][:4])):
            ax = fig.add_subplot(len(names), 4, row * 4 + col + 1)
            for r in runs:
                if tag not in tags[r]:
                    continue
                q = urllib.parse.urlencode({"run": r, "tag": tag})
                pts = np.array(get(port, f"/data/plugin/scalars/scalars?{q}"))
                ax.plot(pts[:, 1], pts[:, 2], "-o" if len(pts) < 20 else "-", ms=3, color=colours[r], lw=1.2)
            if tag.startswith("val/l2p@"):
                ref = tag.replace("val/", "val/interp_")
                for r in runs:
                    if ref in tags[r]:
                        q = urllib.parse.urlencode({"run": r, "tag": ref})
                        pts = np.array(get(port, f"/data/plugin/scalars/scalars?{q}"))
                        ax.plot(pts[:, 1], pts[:, 2], "--", color="0.5", lw=1)
                        break
            ax.set_title(tag, fontsize=9, loc="left")
            ax.tick_params(labelsize=7)
            ax.grid(alpha=0.3)
        fig.text(0.005, 1 - (row + 0.5) / len(names) * 0.9 - 0.06, f"{g}/\n({len(groups[g])} charts)", fontsize=10,
                 weight="bold", va="center")
    handles = [fig.axes[0].plot([], [], color=c)[0] for c in colours.values()]
    fig.legend(handles, [r.split("/")[-1].replace("graph_transformer ", "")[-40:] for r in runs], loc="upper left",
               bbox_to_anchor=(0.01, 0.975), ncol=len(runs), fontsize=8, frameon=False)
    fig.suptitle("TensorBoard Time Series (re-drawn from its scalars API): its three groups, first charts of each; "
                 "dashed grey = interpolation", fontsize=10, y=0.998, x=0.01, ha="left")
    fig.subplots_adjust(left=0.1, right=0.99, top=0.87, bottom=0.05, hspace=0.6, wspace=0.35)
    save(fig, out / "landing.png")


def hparams(port: int, out: Path) -> None:
    """The HParams table view with its default columns (the 5 hparams marked ``differs``, the first 5 metrics)."""
    exp = get(port, "/data/plugin/hparams/experiment", {"experimentName": "", "includeMetrics": True})
    infos = sorted(exp["hparamInfos"], key=lambda h: not h.get("differs"))  # the dashboard's order (stable)
    shown = [h["name"] for h in infos][:5]
    metrics = [m["name"]["tag"] for m in exp["metricInfos"]][:5]
    req = {"experimentName": "", "allowedStatuses": ["STATUS_UNKNOWN", "STATUS_SUCCESS", "STATUS_FAILURE",
                                                      "STATUS_RUNNING"],
           "colParams": [{"hparam": h} for h in shown] + [{"metric": {"group": "", "tag": m}} for m in metrics],
           "aggregationType": "AGGREGATION_AVG", "startIndex": 0, "sliceSize": 50}
    rows = []
    for g in get(port, "/data/plugin/hparams/session_groups", req)["sessionGroups"]:
        vals = {m["name"]["tag"]: m["value"] for m in g.get("metricValues", [])}
        run = g["name"].split("/")[-1].replace("graph_transformer ", "")[-34:]
        rows.append([run] + [str(g["hparams"].get(h, "")) for h in shown]
                    + [f"{vals[m]:.3f}" if m in vals else "" for m in metrics])
    fig = Figure(figsize=(13, 0.6 + 0.32 * (len(rows) + 1)), dpi=80)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(111)
    ax.axis("off")
    table = ax.table(cellText=rows, colLabels=["run"] + shown + metrics, loc="center", cellLoc="center")
    table.auto_set_font_size(False)
    table.set_fontsize(7.5)
    table.auto_set_column_width(list(range(len(shown) + len(metrics) + 1)))
    fig.suptitle(f"HParams table view, default columns (re-drawn from its API; {len(exp['hparamInfos'])} "
                 f"hparams and {len(exp['metricInfos'])} metrics logged)", fontsize=10, x=0.01, ha="left")
    fig.subplots_adjust(left=0.01, right=0.99, top=0.8, bottom=0.02)
    save(fig, out / "hparams.png")


def image(port: int, out: Path, run_suffix: str, tag: str, name: str) -> None:
    tags = get(port, "/data/plugin/images/tags")
    run = next(r for r in sorted(tags) if r.endswith(run_suffix) and tag in tags[r])
    q = urllib.parse.urlencode({"run": run, "tag": tag})
    last = get(port, f"/data/plugin/images/images?{q}")[-1]
    png = get(port, "/data/plugin/images/individualImage?" + last["query"], raw=True)
    img = Image.open(io.BytesIO(png)).convert("RGB")
    img.convert("P", palette=Image.ADAPTIVE, colors=96).save(out / name, optimize=True)
    print(out / name, (out / name).stat().st_size, "bytes")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("logdir")
    ap.add_argument("--out", default=str(Path(__file__).parent))
    ap.add_argument("--run", default="graph_transformer", help="run (name suffix) whose figures are taken")
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    tb, port = start(a.logdir)
    try:
        landing(port, out)
        hparams(port, out)
        image(port, out, a.run, "val/skeleton", "skeleton.png")
        image(port, out, a.run, "val/per_joint", "per_joint.png")
    finally:
        tb.terminate()
        tb.wait(timeout=30)


if __name__ == "__main__":
    main()
